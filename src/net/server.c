/* The visibility server (include/sightline/net.h; docs/vis-server.md, docs/protocol.md).
 *
 * Threads: one libuv loop thread owns every socket and every client's state; `workers` threads
 * compute sets, each with its own reference (a culler of the method, and for pvs a cursor on one
 * shared .slpvs handle) over one scene and one shared acceleration handle. The loop never culls.
 *
 * Per client, at most one job is with the workers. A viewpoint that arrives while one is out waits
 * in `pending`, and a newer one replaces it (coalescing: a client is always answered for its latest
 * viewpoint, never for a backlog). A finished set goes to the client's output queue, which holds at
 * most queue_sets unsent sets beside the one being written: a newer set replaces the oldest unsent
 * one (a slow reader gets fresh sets late, never a growing backlog). So a client holds at most its
 * fixed state, one read buffer of SLVP_CLIENT_BODY_MAX + 4 bytes and queue_sets + 2 messages (the
 * one in the kernel's hands, the unsent ones, the welcome): client_bytes_bound in the stats.
 *
 * Set reuse: with a method that has region sets (net/reference.c), a job looks up the (cell, reach
 * level) of its eye in a cache shared by all workers; a miss computes and encodes the cell's set
 * once, and every client in that cell is then sent the same encoded payload (one blob, counted
 * once; clients hold references). The cache holds at most cache_bytes and drops its oldest entries
 * beyond that (entries being sent live on until their last reference goes).
 *
 * Lifetime: a client whose connection closes while a job of its is out is freed when the job comes
 * back; stopping closes every handle, lets the loop end, then joins the workers. */
#include "net/net_internal.h"
#include "net/visproto.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <uv.h>

typedef struct blob {
    atomic_uint refs;
    bool cached;             /* held by the cache (not counted per client) */
    uint8_t encoding;
    uint32_t count;
    size_t size;             /* payload bytes */
    size_t alloc_size;
    uint8_t data[];
} blob;

typedef struct outmsg {
    struct outmsg *next;
    bool is_set;
    size_t head_len;
    uint8_t head[SLVP_LEN_BYTES + SLVP_WELCOME_FIXED + SLVP_METHOD_MAX + 8];
    blob *payload;           /* NULL for control messages */
    size_t bytes;            /* what it counts against its client */
} outmsg;

typedef struct sl_vis_server_t server;

typedef struct client {
    uv_tcp_t tcp;
    server *srv;
    struct client *prev, *next;
    uint8_t rbuf[SLVP_LEN_BYTES + SLVP_CLIENT_BODY_MAX];
    size_t rlen;
    bool hello;
    sl_camera intrinsics;
    uint32_t last_seq;
    double tokens, token_time;
    /* viewpoints */
    bool has_pending, busy;
    slvp_view pending;
    /* the job with the workers (busy) */
    struct client *job_next;
    slvp_view job_view;
    blob *job_result;
    uint8_t job_validity;
    uint32_t job_cell;
    bool job_failed;
    char job_error[200];
    /* output */
    outmsg *q_head, *q_tail;
    uint32_t q_sets;
    outmsg *writing;
    uv_write_t wreq;
    bool closing, closed;
    /* a refusal (client_refuse): the error queued, then a shutdown, the client's bytes read and
     * dropped until it closes or the linger timer fires */
    bool refusing, counted, linger_open;
    uv_timer_t linger;
    uv_shutdown_t sreq;
    int handles; /* open libuv handles (tcp, linger): freed when the last one has closed */
    size_t mem, mem_peak;
} client;

typedef struct cache_entry {
    struct cache_entry *next;      /* bucket chain */
    struct cache_entry *fifo_next; /* insertion order */
    uint32_t cell, level;
    bool valid;                    /* false: the cell has no region set at this level */
    blob *set;
} cache_entry;

typedef struct worker {
    server *srv;
    pthread_t thread;
    bool started;
    sl_vis_reference ref;
    ZSTD_CCtx *cctx;
    uint32_t *ids;
    uint8_t *scratch;
} worker;

struct sl_vis_server_t {
    const sl_allocator *alloc;
    sl_scene scene;
    sl_scene_accel accel;
    bool owns_accel;
    sl_pvs pvs;
    bool regions;
    char method[SLVP_METHOD_MAX + 1];
    uint32_t object_count;
    uint64_t scene_key;
    uint32_t max_clients, worker_count, max_rate_hz, queue_sets, socket_buffer, max_pixels, hello_timeout_ms;
    uint64_t cache_limit;
    uint32_t set_body_max;
    /* loop */
    uv_loop_t loop;
    uv_tcp_t listener;
    uv_async_t wake;
    pthread_t loop_thread;
    bool loop_started, listener_open, wake_open;
    uint16_t port;
    client *clients;
    uint32_t client_count;
    uint32_t lingering; /* refused clients not yet closed (client_refuse) */
    /* jobs: loop -> workers */
    pthread_mutex_t mu;
    pthread_cond_t cv;
    client *jobs_head, *jobs_tail;
    client *done_head;             /* workers -> loop (LIFO; order does not matter) */
    atomic_bool stopping;          /* written under mu; read without it by the loop (on_connection) */
    worker *workers;
    /* cache */
    pthread_mutex_t cache_mu;
    cache_entry **buckets;
    uint32_t bucket_count;
    cache_entry *fifo_head, *fifo_tail;
    uint64_t cache_bytes;
    /* stats */
    pthread_mutex_t stats_mu;
    sl_vis_server_stats stats;
};

/* ---- memory accounting ---- */

static void stat_add(server *s, uint64_t *field, uint64_t v)
{
    pthread_mutex_lock(&s->stats_mu);
    *field += v;
    pthread_mutex_unlock(&s->stats_mu);
}

static void client_mem(client *c, ptrdiff_t delta)
{
    server *s = c->srv;
    c->mem = (size_t)((ptrdiff_t)c->mem + delta);
    pthread_mutex_lock(&s->stats_mu);
    s->stats.memory_bytes = (uint64_t)((int64_t)s->stats.memory_bytes + delta);
    if (c->mem > c->mem_peak) {
        c->mem_peak = c->mem;
        if (c->mem_peak > s->stats.client_bytes_max)
            s->stats.client_bytes_max = c->mem_peak;
    }
    pthread_mutex_unlock(&s->stats_mu);
}

static blob *blob_new(server *s, size_t size)
{
    size_t total = sizeof(blob) + (size ? size : 1);
    blob *b = net_alloc(s->alloc, total);
    if (!b)
        return NULL;
    atomic_init(&b->refs, 1);
    b->cached = false;
    b->size = size;
    b->alloc_size = total;
    return b;
}

static void blob_release(server *s, blob *b)
{
    if (b && atomic_fetch_sub(&b->refs, 1) == 1)
        net_free(s->alloc, b, b->alloc_size);
}

static outmsg *msg_new(client *c, blob *payload)
{
    server *s = c->srv;
    outmsg *m = net_calloc(s->alloc, sizeof *m);
    if (!m)
        return NULL;
    m->payload = payload;
    m->bytes = sizeof *m + (payload && !payload->cached ? payload->alloc_size : 0);
    client_mem(c, (ptrdiff_t)m->bytes);
    return m;
}

static void msg_free(client *c, outmsg *m)
{
    server *s = c->srv;
    client_mem(c, -(ptrdiff_t)m->bytes);
    blob_release(s, m->payload);
    net_free(s->alloc, m, sizeof *m);
}

/* ---- the cache ---- */

static uint32_t cache_hash(uint32_t cell, uint32_t level)
{
    uint64_t h = ((uint64_t)cell << 6 | level) * 0x9E3779B97F4A7C15ull;
    return (uint32_t)(h >> 32);
}

/* Look up (cell, level); *found tells whether there is an entry; *set gets a reference. */
static bool cache_get(server *s, uint32_t cell, uint32_t level, bool *valid, blob **set)
{
    bool found = false;
    pthread_mutex_lock(&s->cache_mu);
    for (cache_entry *e = s->buckets[cache_hash(cell, level) & (s->bucket_count - 1)]; e; e = e->next)
        if (e->cell == cell && e->level == level) {
            found = true;
            *valid = e->valid;
            *set = e->set;
            if (e->set)
                atomic_fetch_add(&e->set->refs, 1);
            break;
        }
    pthread_mutex_unlock(&s->cache_mu);
    return found;
}

static void cache_unlink(server *s, cache_entry *e)
{
    cache_entry **p = &s->buckets[cache_hash(e->cell, e->level) & (s->bucket_count - 1)];
    while (*p && *p != e)
        p = &(*p)->next;
    if (*p)
        *p = e->next;
}

/* Insert (cell, level) -> set (may be NULL: no region set); returns the set to use (an entry a
 * racing worker put first wins), with a reference for the caller. */
static blob *cache_put(server *s, uint32_t cell, uint32_t level, bool valid, blob *set)
{
    pthread_mutex_lock(&s->cache_mu);
    uint32_t h = cache_hash(cell, level) & (s->bucket_count - 1);
    for (cache_entry *e = s->buckets[h]; e; e = e->next)
        if (e->cell == cell && e->level == level) {
            blob *b = e->set;
            if (b)
                atomic_fetch_add(&b->refs, 1);
            pthread_mutex_unlock(&s->cache_mu);
            blob_release(s, set);
            return b;
        }
    cache_entry *e = net_calloc(s->alloc, sizeof *e);
    if (!e) {
        pthread_mutex_unlock(&s->cache_mu);
        return set; /* not cached: the caller's reference is the only one */
    }
    e->cell = cell;
    e->level = level;
    e->valid = valid;
    e->set = set;
    if (set) {
        set->cached = true;
        atomic_fetch_add(&set->refs, 1); /* the cache's */
    }
    e->next = s->buckets[h];
    s->buckets[h] = e;
    if (s->fifo_tail)
        s->fifo_tail->fifo_next = e;
    else
        s->fifo_head = e;
    s->fifo_tail = e;
    s->cache_bytes += sizeof *e + (set ? set->alloc_size : 0);
    /* over the limit: forget the oldest entries (never the one just added) */
    while (s->cache_bytes > s->cache_limit && s->fifo_head && s->fifo_head != e) {
        cache_entry *old = s->fifo_head;
        s->fifo_head = old->fifo_next;
        cache_unlink(s, old);
        s->cache_bytes -= sizeof *old + (old->set ? old->set->alloc_size : 0);
        blob_release(s, old->set);
        net_free(s->alloc, old, sizeof *old);
    }
    uint64_t bytes = s->cache_bytes;
    pthread_mutex_unlock(&s->cache_mu);
    pthread_mutex_lock(&s->stats_mu);
    s->stats.cache_bytes = bytes;
    s->stats.cache_misses++;
    pthread_mutex_unlock(&s->stats_mu);
    return set;
}

static void cache_clear(server *s)
{
    cache_entry *e = s->fifo_head;
    while (e) {
        cache_entry *n = e->fifo_next;
        blob_release(s, e->set);
        net_free(s->alloc, e, sizeof *e);
        e = n;
    }
    s->fifo_head = s->fifo_tail = NULL;
}

/* ---- workers ---- */

static blob *encode_set(worker *w, uint32_t count, char *why, size_t ws)
{
    server *s = w->srv;
    blob *b = blob_new(s, slvp_payload_bound(s->object_count));
    if (!b) {
        snprintf(why, ws, "out of memory");
        return NULL;
    }
    size_t size;
    uint8_t enc;
    if (!slvp_set_encode(w->cctx, 1, w->ids, count, s->object_count, w->scratch, b->data, &size, &enc, why, ws)) {
        blob_release(s, b);
        return NULL;
    }
    b->size = size;
    b->encoding = enc;
    b->count = count;
    return b;
}

static void camera_of(const client *c, const slvp_view *v, sl_camera *cam)
{
    *cam = c->intrinsics;
    cam->position = (sl_vec3){v->eye[0], v->eye[1], v->eye[2]};
    cam->yaw = v->yaw;
    cam->pitch = v->pitch;
    cam->roll = v->roll;
}

static void run_job(worker *w, client *c)
{
    server *s = w->srv;
    sl_camera cam;
    camera_of(c, &c->job_view, &cam);
    double t0 = net_now();
    sl_error err = {0};
    c->job_result = NULL;
    c->job_failed = false;
    c->job_validity = SL_VIS_POINT;
    c->job_cell = UINT32_MAX;
    uint32_t cell, level;
    if (s->regions && net_reference_region_key(w->ref, &cam, &cell, &level)) {
        bool valid;
        blob *b = NULL;
        if (cache_get(s, cell, level, &valid, &b)) {
            stat_add(s, &s->stats.cache_hits, 1);
        } else {
            uint32_t count;
            if (net_reference_region_set(w->ref, cell, level, w->ids, s->object_count, &count, &valid, &err) != SL_OK) {
                c->job_failed = true;
                snprintf(c->job_error, sizeof c->job_error, "%.190s", err.message);
                return;
            }
            if (valid && !(b = encode_set(w, count, c->job_error, sizeof c->job_error))) {
                c->job_failed = true;
                return;
            }
            stat_add(s, &s->stats.culls, 1);
            b = cache_put(s, cell, level, valid, b);
            valid = b != NULL;
        }
        if (valid && b) {
            c->job_result = b;
            c->job_validity = SL_VIS_CELL;
            c->job_cell = cell;
            pthread_mutex_lock(&s->stats_mu);
            s->stats.cull_ms_total += 1e3 * (net_now() - t0);
            pthread_mutex_unlock(&s->stats_mu);
            return;
        }
        blob_release(s, b);
    }
    uint32_t count;
    if (sl_vis_reference_point(w->ref, &cam, w->ids, s->object_count, &count, &err) != SL_OK) {
        c->job_failed = true;
        snprintf(c->job_error, sizeof c->job_error, "%.190s", err.message);
        return;
    }
    if (!(c->job_result = encode_set(w, count, c->job_error, sizeof c->job_error))) {
        c->job_failed = true;
        return;
    }
    pthread_mutex_lock(&s->stats_mu);
    s->stats.culls++;
    s->stats.cull_ms_total += 1e3 * (net_now() - t0);
    pthread_mutex_unlock(&s->stats_mu);
}

static void *worker_main(void *arg)
{
    worker *w = arg;
    server *s = w->srv;
    pthread_mutex_lock(&s->mu);
    for (;;) {
        while (!s->stopping && !s->jobs_head)
            pthread_cond_wait(&s->cv, &s->mu);
        if (s->stopping)
            break;
        client *c = s->jobs_head;
        s->jobs_head = c->job_next;
        if (!s->jobs_head)
            s->jobs_tail = NULL;
        pthread_mutex_unlock(&s->mu);
        run_job(w, c);
        pthread_mutex_lock(&s->mu);
        c->job_next = s->done_head;
        s->done_head = c;
        pthread_mutex_unlock(&s->mu);
        uv_async_send(&s->wake);
        pthread_mutex_lock(&s->mu);
    }
    pthread_mutex_unlock(&s->mu);
    return NULL;
}

/* ---- the loop: clients ---- */

static void client_close(client *c);
static void uncount(client *c);
static void drop_queue(client *c);
static void on_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf);
static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf);
static void pump(client *c);

static void on_closed(uv_handle_t *h)
{
    client *c = h->data;
    server *s = c->srv;
    if (--c->handles > 0)
        return;
    c->closed = true;
    if (c->busy)
        return; /* freed when its job comes back */
    client_mem(c, -(ptrdiff_t)sizeof *c);
    net_free(s->alloc, c, sizeof *c);
}

static void client_close(client *c)
{
    if (c->closing)
        return;
    server *s = c->srv;
    c->closing = true;
    /* unlink */
    if (c->prev)
        c->prev->next = c->next;
    else
        s->clients = c->next;
    if (c->next)
        c->next->prev = c->prev;
    if (c->counted)
        uncount(c);
    s->lingering -= c->refusing;
    drop_queue(c);
    if (c->linger_open) {
        uv_timer_stop(&c->linger);
        uv_close((uv_handle_t *)&c->linger, on_closed);
    }
    uv_close((uv_handle_t *)&c->tcp, on_closed);
}

/* The client no longer counts among the clients (closed, or refused and lingering). */
static void uncount(client *c)
{
    server *s = c->srv;
    c->counted = false;
    s->client_count--;
    pthread_mutex_lock(&s->stats_mu);
    s->stats.clients = s->client_count;
    pthread_mutex_unlock(&s->stats_mu);
}

/* Unsent messages go now; the one being written goes in its callback (ECANCELED, or written). */
static void drop_queue(client *c)
{
    while (c->q_head) {
        outmsg *m = c->q_head;
        c->q_head = m->next;
        msg_free(c, m);
    }
    c->q_tail = NULL;
    c->q_sets = 0;
}

static void on_linger(uv_timer_t *t) { client_close(t->data); }
static void client_refuse(client *c, uint16_t code, const char *text);
/* No HELLO within hello_timeout_ms of connecting: refused, so that silent connections cannot
 * hold the max_clients places. The timer is the linger one, started at the connection. */
static void on_hello_timeout(uv_timer_t *t)
{
    client *c = t->data;
    char why[96];
    snprintf(why, sizeof why, "no HELLO within %u ms of connecting", c->srv->hello_timeout_ms);
    stat_add(c->srv, &c->srv->stats.protocol_errors, 1);
    client_refuse(c, SLVP_ERR_PROTOCOL, why);
}

/* The refusal is written and the sending side shut: wait for the client's end (on_read). */
static void on_shutdown(uv_shutdown_t *req, int status)
{
    client *c = req->data;
    if (status < 0 && !c->closing)
        client_close(c);
}

/* Say why and close, so that the reason arrives: closing a socket with the client's bytes still
 * unread makes the kernel reset the connection, and the client may see the reset before the
 * error. So the error is queued behind the message being written (whatever else was queued is
 * dropped), the sending side is shut once it is out (on_written), and the client's bytes are
 * read and dropped until it closes, at most SL_NET_LINGER_MS. A refused client no longer counts
 * among the clients; past SL_NET_LINGERING_MAX lingering ones (a flood of bad clients), the
 * refusal is a plain close. */
#define SL_NET_LINGER_MS 2000
#define SL_NET_LINGERING_MAX 64u
static void client_refuse(client *c, uint16_t code, const char *text)
{
    server *s = c->srv;
    if (c->closing || c->refusing)
        return;
    drop_queue(c);
    c->has_pending = false;
    c->rlen = 0; /* what was read is dropped (on_read stops at the refusing message) */
    outmsg *m = s->lingering < SL_NET_LINGERING_MAX ? msg_new(c, NULL) : NULL;
    if (!m || (!c->linger_open && uv_timer_init(&s->loop, &c->linger) != 0)) {
        if (m)
            msg_free(c, m);
        client_close(c);
        return;
    }
    if (!c->linger_open) { /* else the HELLO timer's handle, reused */
        c->linger.data = c;
        c->linger_open = true;
        c->handles++;
    }
    c->refusing = true;
    s->lingering++;
    uncount(c);
    m->head_len = slvp_write_error(m->head, code, text);
    uv_timer_start(&c->linger, on_linger, SL_NET_LINGER_MS, 0);
    int rc = uv_read_start((uv_stream_t *)&c->tcp, on_alloc, on_read);
    if (rc != 0 && rc != UV_EALREADY) {
        msg_free(c, m);
        client_close(c);
        return;
    }
    c->q_head = c->q_tail = m;
    pump(c);
}

/* After the last write of a refusal: shut the sending side. */
static void refusal_sent(client *c)
{
    c->sreq.data = c;
    if (uv_shutdown(&c->sreq, (uv_stream_t *)&c->tcp, on_shutdown) != 0)
        client_close(c);
}


static void on_written(uv_write_t *req, int status)
{
    client *c = req->data;
    outmsg *m = c->writing;
    c->writing = NULL;
    if (m) {
        if (status == 0) {
            stat_add(c->srv, &c->srv->stats.bytes_out, m->head_len + (m->payload ? m->payload->size : 0));
            if (m->is_set)
                stat_add(c->srv, &c->srv->stats.sets_sent, 1);
        }
        msg_free(c, m);
    }
    if (c->closing) {
        return;
    }
    if (status < 0) {
        client_close(c);
        return;
    }
    if (c->refusing && !c->q_head) {
        refusal_sent(c);
        return;
    }
    pump(c);
}

static void pump(client *c)
{
    if (c->writing || c->closing || !c->q_head)
        return;
    outmsg *m = c->q_head;
    c->q_head = m->next;
    if (!c->q_head)
        c->q_tail = NULL;
    if (m->is_set)
        c->q_sets--;
    c->writing = m;
    uv_buf_t bufs[2] = {uv_buf_init((char *)m->head, (unsigned)m->head_len),
                        uv_buf_init(m->payload ? (char *)m->payload->data : NULL,
                                    m->payload ? (unsigned)m->payload->size : 0)};
    c->wreq.data = c;
    int rc = uv_write(&c->wreq, (uv_stream_t *)&c->tcp, bufs, m->payload && m->payload->size ? 2 : 1, on_written);
    if (rc < 0) {
        c->writing = NULL;
        msg_free(c, m);
        client_close(c);
    }
}

static void enqueue(client *c, outmsg *m)
{
    if (m->is_set) {
        /* bounded: an unsent older set is stale once a newer one exists */
        while (c->q_sets >= c->srv->queue_sets) {
            outmsg **p = &c->q_head, *prev = NULL;
            while (*p && !(*p)->is_set) {
                prev = *p;
                p = &(*p)->next;
            }
            outmsg *old = *p;
            *p = old->next;
            if (c->q_tail == old)
                c->q_tail = prev;
            c->q_sets--;
            msg_free(c, old);
            stat_add(c->srv, &c->srv->stats.sets_dropped, 1);
        }
        c->q_sets++;
    }
    m->next = NULL;
    if (c->q_tail)
        c->q_tail->next = m;
    else
        c->q_head = m;
    c->q_tail = m;
    pump(c);
}

static void submit(client *c)
{
    server *s = c->srv;
    if (c->busy || !c->has_pending || c->closing || c->refusing)
        return;
    c->busy = true;
    c->has_pending = false;
    c->job_view = c->pending;
    c->job_next = NULL;
    pthread_mutex_lock(&s->mu);
    if (s->jobs_tail)
        s->jobs_tail->job_next = c;
    else
        s->jobs_head = c;
    s->jobs_tail = c;
    pthread_cond_signal(&s->cv);
    pthread_mutex_unlock(&s->mu);
}

static void job_done(client *c)
{
    server *s = c->srv;
    c->busy = false;
    if (c->closed) {
        blob_release(s, c->job_result);
        client_mem(c, -(ptrdiff_t)sizeof *c);
        net_free(s->alloc, c, sizeof *c);
        return;
    }
    if (c->closing || c->refusing) {
        blob_release(s, c->job_result);
        return;
    }
    if (c->job_failed) {
        client_refuse(c, SLVP_ERR_INTERNAL, c->job_error);
        return;
    }
    outmsg *m = msg_new(c, c->job_result);
    if (!m) {
        blob_release(s, c->job_result);
        client_refuse(c, SLVP_ERR_INTERNAL, "server out of memory");
        return;
    }
    blob *b = c->job_result;
    slvp_set h = {.seq = c->job_view.seq, .validity = c->job_validity, .encoding = b->encoding, .cell = c->job_cell,
                  .count = b->count, .payload_size = (uint32_t)b->size};
    m->is_set = true;
    m->head_len = slvp_write_set_header(m->head, &h);
    enqueue(c, m);
    submit(c);
}

static void on_wake(uv_async_t *a)
{
    server *s = a->data;
    pthread_mutex_lock(&s->mu);
    client *done = s->done_head, *cancelled = NULL;
    s->done_head = NULL;
    bool stopping = s->stopping;
    if (stopping) {
        /* the workers are gone (destroy joined them first): jobs never taken come back undone */
        cancelled = s->jobs_head;
        s->jobs_head = s->jobs_tail = NULL;
    }
    pthread_mutex_unlock(&s->mu);
    if (stopping) {
        while (s->clients)
            client_close(s->clients);
        if (s->listener_open) {
            uv_close((uv_handle_t *)&s->listener, NULL);
            s->listener_open = false;
        }
    }
    while (done) {
        client *n = done->job_next;
        job_done(done);
        done = n;
    }
    while (cancelled) {
        client *n = cancelled->job_next;
        cancelled->job_result = NULL;
        cancelled->job_failed = false;
        job_done(cancelled);
        cancelled = n;
    }
    if (stopping && s->wake_open) {
        uv_close((uv_handle_t *)&s->wake, NULL);
        s->wake_open = false;
    }
}

static bool handle_message(client *c, const uint8_t *body, uint32_t len)
{
    server *s = c->srv;
    char why[256];
    uint8_t type = slvp_type_of(body, len);
    if (!c->hello) {
        slvp_hello h;
        if (type != SLVP_HELLO) {
            snprintf(why, sizeof why, "expected HELLO (type 1) first, got type %u", type);
            goto bad;
        }
        if (!slvp_read_hello(body, len, &h, why, sizeof why)) {
            stat_add(s, &s->stats.protocol_errors, 1);
            /* code 2 only for a HELLO of another version: right size and magic, other version */
            bool version = len == SLVP_HELLO_BODY && slvp_u32(body + 1) == SLVP_MAGIC &&
                           body[5] + 256 * body[6] != SLVP_VERSION;
            client_refuse(c, version ? SLVP_ERR_VERSION : SLVP_ERR_PROTOCOL, why);
            return false;
        }
        sl_camera cam = sl_camera_default();
        cam.projection = h.projection ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE;
        cam.fov_y = h.projection ? cam.fov_y : h.fov_y;
        cam.ortho_height = h.projection ? h.ortho_height : cam.ortho_height;
        cam.near_plane = h.near_plane;
        cam.far_plane = h.far_plane;
        cam.width = h.width;
        cam.height = h.height;
        sl_error err = {0};
        if (sl_camera_validate(&cam, &err) != SL_OK) {
            snprintf(why, sizeof why, "HELLO: camera: %.200s", err.message);
            goto bad;
        }
        if ((uint64_t)h.width * h.height > s->max_pixels) {
            stat_add(s, &s->stats.protocol_errors, 1);
            snprintf(why, sizeof why, "HELLO offset 24: width x height %u x %u: more than this server's %u pixels",
                     h.width, h.height, s->max_pixels);
            client_refuse(c, SLVP_ERR_LIMIT, why);
            return false;
        }
        c->intrinsics = cam;
        c->hello = true;
        if (c->linger_open)
            uv_timer_stop(&c->linger);
        outmsg *m = msg_new(c, NULL);
        if (!m) {
            client_refuse(c, SLVP_ERR_INTERNAL, "server out of memory");
            return false;
        }
        slvp_welcome w = {.version = SLVP_VERSION, .flags = s->regions ? 1 : 0, .object_count = s->object_count,
                          .scene_key = s->scene_key, .max_rate_hz = s->max_rate_hz, .max_body = s->set_body_max};
        snprintf(w.method, sizeof w.method, "%s", s->method);
        m->head_len = slvp_write_welcome(m->head, &w);
        enqueue(c, m);
        return true;
    }
    if (type != SLVP_VIEW) {
        snprintf(why, sizeof why, "expected VIEW (type 3), got type %u", type);
        goto bad;
    }
    slvp_view v;
    if (!slvp_read_view(body, len, c->last_seq, &v, why, sizeof why))
        goto bad;
    /* token bucket: a second's worth of burst, max_rate_hz refill */
    double now = net_now();
    c->tokens = fmin((double)s->max_rate_hz, c->tokens + (now - c->token_time) * s->max_rate_hz);
    c->token_time = now;
    if (c->tokens < 1.0) {
        stat_add(s, &s->stats.rate_limited, 1);
        snprintf(why, sizeof why, "more than %u viewpoints per second", s->max_rate_hz);
        client_refuse(c, SLVP_ERR_RATE, why);
        return false;
    }
    c->tokens -= 1.0;
    c->last_seq = v.seq;
    pthread_mutex_lock(&s->stats_mu);
    s->stats.views++;
    if (c->has_pending)
        s->stats.views_coalesced++;
    pthread_mutex_unlock(&s->stats_mu);
    c->pending = v;
    c->has_pending = true;
    submit(c);
    return true;
bad:
    stat_add(s, &s->stats.protocol_errors, 1);
    client_refuse(c, SLVP_ERR_PROTOCOL, why);
    return false;
}

static void on_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf)
{
    (void)suggested;
    client *c = h->data;
    buf->base = (char *)c->rbuf + c->rlen;
    buf->len = sizeof c->rbuf - c->rlen;
}

static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf)
{
    (void)buf;
    client *c = st->data;
    if (c->closing)
        return;
    if (nread < 0) {
        if (nread == UV_EOF && c->rlen > 0 && !c->refusing) {
            /* the stream ended inside a message: say so (the client may still read after
             * shutting its side); the refusal's next read meets the end again and closes */
            char why[160];
            if (c->rlen < SLVP_LEN_BYTES)
                snprintf(why, sizeof why, "offset 0: the stream ended inside a length prefix (%zu of %u bytes)",
                         c->rlen, (unsigned)SLVP_LEN_BYTES);
            else {
                snprintf(why, sizeof why, "offset %zu: the stream ended inside a message of %u bytes (%zu received)",
                         c->rlen, slvp_u32(c->rbuf), c->rlen - SLVP_LEN_BYTES);
            }
            stat_add(c->srv, &c->srv->stats.protocol_errors, 1);
            client_refuse(c, SLVP_ERR_PROTOCOL, why);
            return;
        }
        client_close(c); /* EOF or error */
        return;
    }
    if (c->refusing) { /* read and dropped (client_refuse) */
        c->rlen = 0;
        return;
    }
    stat_add(c->srv, &c->srv->stats.bytes_in, (uint64_t)nread);
    c->rlen += (size_t)nread;
    size_t off = 0;
    for (;;) {
        uint32_t len;
        char why[160];
        int r = slvp_frame(c->rbuf + off, c->rlen - off, SLVP_CLIENT_BODY_MAX, &len, why, sizeof why);
        if (r < 0) {
            stat_add(c->srv, &c->srv->stats.protocol_errors, 1);
            client_refuse(c, SLVP_ERR_LIMIT, why);
            return;
        }
        if (r == 0)
            break;
        if (!handle_message(c, c->rbuf + off + SLVP_LEN_BYTES, len))
            return;
        off += SLVP_LEN_BYTES + len;
    }
    memmove(c->rbuf, c->rbuf + off, c->rlen - off);
    c->rlen -= off;
}

static void on_connection(uv_stream_t *l, int status)
{
    server *s = l->data;
    if (status < 0 || s->stopping)
        return;
    client *c = net_calloc(s->alloc, sizeof *c);
    if (!c)
        return;
    c->srv = s;
    uv_tcp_init(&s->loop, &c->tcp);
    c->tcp.data = c;
    c->handles = 1;
    client_mem(c, (ptrdiff_t)sizeof *c);
    if (uv_accept(l, (uv_stream_t *)&c->tcp) != 0) {
        c->closing = true;
        uv_close((uv_handle_t *)&c->tcp, on_closed);
        return;
    }
    uv_tcp_nodelay(&c->tcp, 1);
    if (s->socket_buffer) {
        int size = (int)s->socket_buffer;
        uv_send_buffer_size((uv_handle_t *)&c->tcp, &size);
    }
    c->next = s->clients;
    if (s->clients)
        s->clients->prev = c;
    s->clients = c;
    s->client_count++;
    c->counted = true;
    c->tokens = s->max_rate_hz;
    c->token_time = net_now();
    pthread_mutex_lock(&s->stats_mu);
    s->stats.clients = s->client_count;
    s->stats.clients_total++;
    pthread_mutex_unlock(&s->stats_mu);
    if (s->client_count > s->max_clients) {
        stat_add(s, &s->stats.clients_refused, 1);
        char why[96];
        snprintf(why, sizeof why, "server full: %u clients at most", s->max_clients);
        client_refuse(c, SLVP_ERR_FULL, why);
        return;
    }
    if (uv_timer_init(&s->loop, &c->linger) == 0) {
        c->linger.data = c;
        c->linger_open = true;
        c->handles++;
        uv_timer_start(&c->linger, on_hello_timeout, s->hello_timeout_ms, 0);
    }
    uv_read_start((uv_stream_t *)&c->tcp, on_alloc, on_read);
}

static void *loop_main(void *arg)
{
    server *s = arg;
    uv_run(&s->loop, UV_RUN_DEFAULT);
    return NULL;
}

/* ---- create / destroy ---- */

static void stop_workers(server *s)
{
    pthread_mutex_lock(&s->mu);
    s->stopping = true;
    pthread_cond_broadcast(&s->cv);
    pthread_mutex_unlock(&s->mu);
    for (uint32_t i = 0; s->workers && i < s->worker_count; i++)
        if (s->workers[i].started)
            pthread_join(s->workers[i].thread, NULL);
}

static void close_walk(uv_handle_t *h, void *arg)
{
    (void)arg;
    if (!uv_is_closing(h))
        uv_close(h, NULL);
}

void sl_vis_server_destroy(sl_vis_server s)
{
    if (!s)
        return;
    if (s->loop_started) {
        /* workers first: each finishes its job and hands it back; then the loop closes all */
        stop_workers(s);
        uv_async_send(&s->wake);
        /* the loop thread closes the clients and the listener in on_wake; the wake handle last */
        pthread_join(s->loop_thread, NULL);
    } else {
        stop_workers(s);
    }
    /* whatever is left (jobs handed back after the loop ended, handles of a loop that never ran) */
    client *done = s->done_head;
    s->done_head = NULL;
    while (done) {
        client *n = done->job_next;
        done->busy = false;
        blob_release(s, done->job_result);
        if (done->closed)
            net_free(s->alloc, done, sizeof *done);
        done = n;
    }
    if (uv_loop_alive(&s->loop) || s->wake_open || s->listener_open) {
        uv_walk(&s->loop, close_walk, NULL);
        uv_run(&s->loop, UV_RUN_DEFAULT);
    }
    uv_loop_close(&s->loop);
    for (uint32_t i = 0; s->workers && i < s->worker_count; i++) {
        worker *w = &s->workers[i];
        sl_vis_reference_destroy(w->ref);
        ZSTD_freeCCtx(w->cctx);
        net_free(s->alloc, w->ids, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
        net_free(s->alloc, w->scratch, slvp_scratch_bytes(s->object_count));
    }
    net_free(s->alloc, s->workers, (size_t)s->worker_count * sizeof(worker));
    cache_clear(s);
    net_free(s->alloc, s->buckets, (size_t)s->bucket_count * sizeof(cache_entry *));
    if (s->pvs)
        sl_pvs_destroy(s->pvs);
    if (s->owns_accel)
        sl_scene_accel_destroy(s->accel);
    pthread_mutex_destroy(&s->mu);
    pthread_cond_destroy(&s->cv);
    pthread_mutex_destroy(&s->cache_mu);
    pthread_mutex_destroy(&s->stats_mu);
    net_free(s->alloc, s, sizeof *s);
}

sl_status sl_vis_server_create(sl_scene scene, const sl_vis_server_options *o, sl_vis_server *out, sl_error *err)
{
    *out = NULL;
    sl_vis_server_options d = {0};
    if (!o)
        o = &d;
    if (!scene)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: no scene");
    if (!o->method)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: no method (a spec such as cullmap or pvs:file=X.slpvs)");
    if (strlen(o->method) > SLVP_METHOD_MAX)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: method spec longer than %u characters", SLVP_METHOD_MAX);
    uint32_t max_clients = o->max_clients ? o->max_clients : 256;
    uint32_t workers = o->workers ? o->workers : 2;
    uint32_t rate = o->max_rate_hz ? o->max_rate_hz : 240;
    uint32_t queue = o->queue_sets ? o->queue_sets : 1;
    if (max_clients > SL_VIS_MAX_CLIENTS)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: max_clients %u: at most %u", max_clients,
                        SL_VIS_MAX_CLIENTS);
    if (workers > SL_MAX_THREADS)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: workers %u: at most %u", workers, SL_MAX_THREADS);
    if (rate > SL_VIS_MAX_RATE_HZ)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: max_rate_hz %u: at most %u", rate,
                        SL_VIS_MAX_RATE_HZ);
    if (queue > SL_VIS_MAX_QUEUE_SETS)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: queue_sets %u: at most %u", queue,
                        SL_VIS_MAX_QUEUE_SETS);
    uint32_t max_pixels = o->max_pixels ? o->max_pixels : 3840u * 2160u;
    if (o->hello_timeout_ms > 3600000)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: hello_timeout_ms %u: at most 3600000 (an hour)",
                        o->hello_timeout_ms);
    if (max_pixels > SL_VIS_MAX_PIXELS)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: max_pixels %u: at most 2^28 (16384 x 16384)",
                        max_pixels);
    if (o->socket_buffer > (1u << 30))
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: socket_buffer %u: at most 2^30 bytes",
                        o->socket_buffer);
    if (sl_scene_object_count(scene) > SLVP_OBJECTS_MAX)
        return net_fail(err, SL_ERROR_LIMIT, "vis server: %u objects, the protocol takes at most %u",
                        sl_scene_object_count(scene), SLVP_OBJECTS_MAX);
    const sl_allocator *a = o->alloc ? o->alloc : sl_default_allocator();
    server *s = net_calloc(a, sizeof *s);
    if (!s)
        return net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis server: out of memory");
    s->alloc = a;
    s->scene = scene;
    pthread_mutex_init(&s->mu, NULL);
    pthread_cond_init(&s->cv, NULL);
    pthread_mutex_init(&s->cache_mu, NULL);
    pthread_mutex_init(&s->stats_mu, NULL);
    uv_loop_init(&s->loop);
    snprintf(s->method, sizeof s->method, "%s", o->method);
    s->object_count = sl_scene_object_count(scene);
    s->scene_key = sl_pvs_scene_key(scene);
    s->max_clients = max_clients;
    s->max_rate_hz = rate;
    s->queue_sets = queue;
    s->socket_buffer = o->socket_buffer;
    s->max_pixels = max_pixels;
    s->hello_timeout_ms = o->hello_timeout_ms ? o->hello_timeout_ms : 10000;
    s->cache_limit = o->cache_bytes ? o->cache_bytes : 64ull << 20;
    s->set_body_max = slvp_set_body_max(s->object_count);
    sl_status st = SL_OK;
    s->accel = o->accel;
    if (!s->accel) {
        if ((st = sl_scene_accel_create(scene, NULL, &s->accel, err)) != SL_OK)
            goto fail;
        s->owns_accel = true;
    }
    /* the method's PVS, opened once for every worker (cursors are per worker) */
    char name[64], opts[SLVP_METHOD_MAX + 1];
    if ((st = net_split_spec(o->method, name, sizeof name, opts, sizeof opts, err)) != SL_OK)
        goto fail;
    if (!o->no_reuse && strcmp(name, "pvs") == 0) {
        char file[4096];
        if (!net_spec_file(opts, file, sizeof file)) {
            st = net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: method pvs needs file=PATH");
            goto fail;
        }
        if ((st = sl_pvs_open(file, 0, a, &s->pvs, err)) != SL_OK ||
            (st = sl_pvs_check_scene(s->pvs, scene, err)) != SL_OK)
            goto fail;
    }
    s->worker_count = workers;
    s->workers = net_calloc(a, (size_t)workers * sizeof(worker));
    if (!s->workers) {
        st = net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis server: out of memory");
        goto fail;
    }
    for (uint32_t i = 0; i < workers; i++) {
        worker *w = &s->workers[i];
        w->srv = s;
        if ((st = net_reference_create(scene, o->method, !o->no_reuse, s->accel, s->pvs, a, &w->ref, err)) != SL_OK)
            goto fail;
        w->cctx = ZSTD_createCCtx();
        w->ids = net_alloc(a, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
        w->scratch = net_alloc(a, slvp_scratch_bytes(s->object_count));
        if (!w->cctx || !w->ids || !w->scratch) {
            st = net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis server: out of memory");
            goto fail;
        }
    }
    s->regions = sl_vis_reference_has_regions(s->workers[0].ref);
    s->bucket_count = 1024;
    s->buckets = net_calloc(a, (size_t)s->bucket_count * sizeof(cache_entry *));
    if (!s->buckets) {
        st = net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis server: out of memory");
        goto fail;
    }
    /* memory one client can hold: its state, and queue_sets unsent sets + the one being written +
     * the welcome, each a message and (point sets) a payload of at most the bitset */
    s->stats.client_bytes_bound = sizeof(client) + (uint64_t)(queue + 2) *
        (sizeof(outmsg) + sizeof(blob) + slvp_payload_bound(s->object_count) + 1);
    /* listen */
    const char *host = o->host ? o->host : "127.0.0.1";
    struct sockaddr_storage addr;
    int rc = strchr(host, ':') ? uv_ip6_addr(host, o->port, (struct sockaddr_in6 *)&addr)
                               : uv_ip4_addr(host, o->port, (struct sockaddr_in *)&addr);
    if (rc != 0) {
        st = net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis server: host '%s': not an IPv4 or IPv6 address", host);
        goto fail;
    }
    uv_tcp_init(&s->loop, &s->listener);
    s->listener.data = s;
    s->listener_open = true;
    if ((rc = uv_tcp_bind(&s->listener, (const struct sockaddr *)&addr, 0)) != 0 ||
        (rc = uv_listen((uv_stream_t *)&s->listener, 128, on_connection)) != 0) {
        st = net_fail(err, SL_ERROR_IO, "vis server: listen on %s port %u: %s", host, o->port, uv_strerror(rc));
        goto fail;
    }
    struct sockaddr_storage bound;
    int len = sizeof bound;
    uv_tcp_getsockname(&s->listener, (struct sockaddr *)&bound, &len);
    s->port = ntohs(bound.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&bound)->sin6_port
                                                : ((struct sockaddr_in *)&bound)->sin_port);
    uv_async_init(&s->loop, &s->wake, on_wake);
    s->wake.data = s;
    s->wake_open = true;
    for (uint32_t i = 0; i < workers; i++) {
        if (net_thread_create(&s->workers[i].thread, worker_main, &s->workers[i]) != 0) {
            st = net_fail(err, SL_ERROR_INTERNAL, "vis server: cannot start worker thread %u", i);
            goto fail;
        }
        s->workers[i].started = true;
    }
    if (net_thread_create(&s->loop_thread, loop_main, s) != 0) {
        st = net_fail(err, SL_ERROR_INTERNAL, "vis server: cannot start the loop thread");
        goto fail;
    }
    s->loop_started = true;
    *out = s;
    return SL_OK;
fail:
    sl_vis_server_destroy(s);
    return st;
}

uint16_t sl_vis_server_port(sl_vis_server s) { return s ? s->port : 0; }

void sl_vis_server_get_stats(sl_vis_server s, sl_vis_server_stats *out)
{
    pthread_mutex_lock(&s->stats_mu);
    *out = s->stats;
    pthread_mutex_unlock(&s->stats_mu);
}

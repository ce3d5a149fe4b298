/* The visibility client (include/sightline/net.h; docs/vis-server.md).
 *
 * A libuv loop on a thread of its own holds the connection: it connects (again reconnect_ms after
 * any failure or loss), writes HELLO and then the latest viewpoint whenever the previous write is
 * done (viewpoints sent faster than the socket takes them coalesce here too: only the newest
 * waits), and reads messages into a buffer sized from the server's WELCOME (the longest SET body
 * it may send; anything longer is refused before a byte of it is buffered).
 *
 * Sets are triple-buffered: the loop decodes into `decode`; a complete, valid set is swapped with
 * `ready` under the mutex; sl_vis_client_acquire swaps `ready` with `front`, the set the caller
 * displays. So the displayed set changes only when the caller asks, and only to a whole set. */
#include "net/net_internal.h"
#include "net/visproto.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <uv.h>

typedef struct set_buffer {
    uint32_t *ids;
    uint32_t count, seq, cell;
    sl_vis_validity validity;
    double received;
} set_buffer;

typedef struct conn {
    uv_tcp_t tcp;
    uv_connect_t creq;
    uv_write_t wreq;
    struct sl_vis_client_t *cl;
    uint8_t *rbuf;
    size_t rlen, rcap;
    uint8_t wbuf[64];
    bool writing, hello_sent, connected, closing;
    uint32_t view_sent; /* the newest seq written on this connection */
    uint32_t set_seq;   /* the seq of the last set received on it */
} conn;

struct sl_vis_client_t {
    uint32_t expect_objects; /* sl_vis_client_options.object_count (0: any) */
    const sl_allocator *alloc;
    char host[64];
    uint16_t port;
    sl_camera intrinsics;
    uint32_t reconnect_ms;
    uv_loop_t loop;
    uv_async_t wake;
    uv_timer_t retry;
    pthread_t thread;
    bool thread_started;
    conn *cn;
    /* shared with the caller's threads */
    pthread_mutex_t mu;
    pthread_cond_t cv;
    atomic_bool stopping;     /* written under mu; the loop also reads it without */
    uint32_t next_seq;
    slvp_view latest;
    bool latest_unsent;
    uint32_t newest_seq;      /* newest seq answered by a received set */
    bool ready_new;
    set_buffer bufs[3];
    int front, ready, decode; /* indices into bufs */
    uint32_t capacity;        /* ids each buffer holds (the scene's object count) */
    uint8_t *scratch;
    ZSTD_DCtx *dctx;
    sl_vis_client_stats stats;
};

static void schedule_retry(sl_vis_client c);

static void set_error(sl_vis_client c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void set_error(sl_vis_client c, const char *fmt, ...)
{
    pthread_mutex_lock(&c->mu);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->stats.last_error, sizeof c->stats.last_error, fmt, ap);
    va_end(ap);
    c->stats.errors++;
    pthread_mutex_unlock(&c->mu);
}

static void on_conn_closed(uv_handle_t *h)
{
    conn *k = h->data;
    sl_vis_client c = k->cl;
    net_free(c->alloc, k->rbuf, k->rcap);
    net_free(c->alloc, k, sizeof *k);
}

static void conn_drop(sl_vis_client c)
{
    conn *k = c->cn;
    if (!k || k->closing)
        return;
    k->closing = true;
    c->cn = NULL;
    pthread_mutex_lock(&c->mu);
    c->stats.connected = false;
    /* the latest viewpoint is sent again on the next connection */
    if (c->latest.seq)
        c->latest_unsent = true;
    pthread_mutex_unlock(&c->mu);
    uv_close((uv_handle_t *)&k->tcp, on_conn_closed);
    schedule_retry(c);
}

static void pump(sl_vis_client c);

static void on_written(uv_write_t *req, int status)
{
    conn *k = req->data;
    k->writing = false;
    if (k->closing)
        return;
    if (status < 0) {
        conn_drop(k->cl);
        return;
    }
    pump(k->cl);
}

static slvp_hello hello_of(const sl_camera *cam)
{
    return (slvp_hello){.version = SLVP_VERSION,
                        .projection = cam->projection == SL_ORTHOGRAPHIC,
                        .fov_y = cam->fov_y,
                        .ortho_height = cam->ortho_height,
                        .near_plane = cam->near_plane,
                        .far_plane = cam->far_plane,
                        .width = cam->width,
                        .height = cam->height};
}

static void pump(sl_vis_client c)
{
    conn *k = c->cn;
    if (!k || !k->connected || k->writing || k->closing)
        return;
    size_t n = 0;
    if (!k->hello_sent) {
        slvp_hello h = hello_of(&c->intrinsics);
        n = slvp_write_hello(k->wbuf, &h);
        k->hello_sent = true;
    } else {
        pthread_mutex_lock(&c->mu);
        if (c->latest_unsent) {
            n = slvp_write_view(k->wbuf, &c->latest);
            k->view_sent = c->latest.seq;
            c->latest_unsent = false;
            c->stats.views_sent++;
        }
        pthread_mutex_unlock(&c->mu);
    }
    if (!n)
        return;
    uv_buf_t b = uv_buf_init((char *)k->wbuf, (unsigned)n);
    k->wreq.data = k;
    k->writing = true;
    if (uv_write(&k->wreq, (uv_stream_t *)&k->tcp, &b, 1, on_written) < 0) {
        k->writing = false;
        conn_drop(c);
        return;
    }
    pthread_mutex_lock(&c->mu);
    c->stats.bytes_out += n;
    pthread_mutex_unlock(&c->mu);
}

static bool handle(sl_vis_client c, const uint8_t *body, uint32_t len)
{
    char why[256];
    uint8_t type = slvp_type_of(body, len);
    if (type == SLVP_ERROR) {
        slvp_errmsg e;
        if (!slvp_read_error(body, len, &e, why, sizeof why))
            set_error(c, "server sent a bad ERROR: %s", why);
        else
            set_error(c, "server: error %u: %s", e.code, e.text);
        return false;
    }
    if (type == SLVP_WELCOME) {
        slvp_welcome w;
        if (!slvp_read_welcome(body, len, &w, why, sizeof why)) {
            set_error(c, "%s", why);
            return false;
        }
        if (c->expect_objects && w.object_count != c->expect_objects) {
            set_error(c, "server's scene has %u objects, this client expects %u", w.object_count, c->expect_objects);
            return false;
        }
        if (c->capacity && w.object_count != c->capacity) {
            set_error(c, "server's scene has %u objects, it had %u before the reconnection", w.object_count, c->capacity);
            return false;
        }
        if (!c->capacity) {
            size_t n = w.object_count ? w.object_count : 1;
            for (int i = 0; i < 3; i++)
                if (!(c->bufs[i].ids = net_alloc(c->alloc, n * sizeof(uint32_t)))) {
                    set_error(c, "out of memory for %u ids", w.object_count);
                    return false;
                }
            c->scratch = net_alloc(c->alloc, slvp_scratch_bytes(w.object_count));
            if (!c->scratch) {
                set_error(c, "out of memory");
                return false;
            }
            c->capacity = (uint32_t)n;
        }
        conn *k = c->cn;
        size_t cap = SLVP_LEN_BYTES + (size_t)w.max_body;
        if (cap > k->rcap) {
            uint8_t *nb = net_alloc(c->alloc, cap);
            if (!nb) {
                set_error(c, "out of memory for a %zu-byte buffer", cap);
                return false;
            }
            memcpy(nb, k->rbuf, k->rlen);
            net_free(c->alloc, k->rbuf, k->rcap);
            k->rbuf = nb;
            k->rcap = cap;
        }
        pthread_mutex_lock(&c->mu);
        c->stats.object_count = w.object_count;
        c->stats.scene_key = w.scene_key;
        c->stats.regions = w.flags & 1;
        snprintf(c->stats.method, sizeof c->stats.method, "%s", w.method);
        c->stats.max_rate_hz = w.max_rate_hz;
        c->stats.connected = true;
        pthread_mutex_unlock(&c->mu);
        return true;
    }
    if (type == SLVP_SET) {
        if (!c->capacity || !c->stats.connected) {
            set_error(c, "SET before WELCOME");
            return false;
        }
        slvp_set m;
        set_buffer *d = &c->bufs[c->decode];
        if (!slvp_read_set(body, len, c->stats.object_count, &m, why, sizeof why) ||
            !slvp_set_decode(c->dctx, &m, c->stats.object_count, c->scratch, d->ids, why, sizeof why)) {
            set_error(c, "%s", why);
            return false;
        }
        /* a set answers a viewpoint sent on this connection, and sets arrive in increasing seq */
        conn *k = c->cn;
        if (!k)
            return false;
        if (m.seq > k->view_sent) {
            set_error(c, "SET seq %u answers no viewpoint sent on this connection (the newest is %u)", m.seq,
                      k->view_sent);
            return false;
        }
        if (m.seq <= k->set_seq) {
            set_error(c, "SET seq %u after seq %u: sets arrive in increasing seq", m.seq, k->set_seq);
            return false;
        }
        k->set_seq = m.seq;
        d->count = m.count;
        d->seq = m.seq;
        d->validity = m.validity ? SL_VIS_CELL : SL_VIS_POINT;
        d->cell = m.validity ? m.cell : SL_NONE;
        d->received = net_now();
        pthread_mutex_lock(&c->mu);
        int t = c->ready;
        c->ready = c->decode;
        c->decode = t;
        c->ready_new = true;
        if (m.seq > c->newest_seq)
            c->newest_seq = m.seq;
        c->stats.sets_received++;
        pthread_cond_broadcast(&c->cv);
        pthread_mutex_unlock(&c->mu);
        return true;
    }
    set_error(c, "unexpected message type %u from the server", type);
    return false;
}

static void on_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf)
{
    (void)suggested;
    conn *k = h->data;
    buf->base = (char *)k->rbuf + k->rlen;
    buf->len = k->rcap - k->rlen;
}

static void on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf)
{
    (void)buf;
    conn *k = st->data;
    sl_vis_client c = k->cl;
    if (k->closing)
        return;
    if (nread < 0) {
        conn_drop(c);
        return;
    }
    pthread_mutex_lock(&c->mu);
    c->stats.bytes_in += (uint64_t)nread;
    pthread_mutex_unlock(&c->mu);
    k->rlen += (size_t)nread;
    size_t off = 0;
    for (;;) {
        uint32_t len;
        char why[160];
        int r = slvp_frame(k->rbuf + off, k->rlen - off, (uint32_t)(k->rcap - SLVP_LEN_BYTES), &len, why, sizeof why);
        if (r < 0) {
            set_error(c, "%s", why);
            conn_drop(c);
            return;
        }
        if (r == 0)
            break;
        if (!handle(c, k->rbuf + off + SLVP_LEN_BYTES, len)) {
            conn_drop(c);
            return;
        }
        off += SLVP_LEN_BYTES + len;
    }
    memmove(k->rbuf, k->rbuf + off, k->rlen - off);
    k->rlen -= off;
}

static void on_connect(uv_connect_t *req, int status)
{
    conn *k = req->data;
    sl_vis_client c = k->cl;
    if (k->closing)
        return;
    if (status < 0) {
        conn_drop(c);
        return;
    }
    k->connected = true;
    pthread_mutex_lock(&c->mu);
    c->stats.connects++;
    pthread_mutex_unlock(&c->mu);
    uv_tcp_nodelay(&k->tcp, 1);
    uv_read_start((uv_stream_t *)&k->tcp, on_alloc, on_read);
    pump(c);
}

static void try_connect(sl_vis_client c)
{
    if (c->stopping || c->cn)
        return;
    conn *k = net_calloc(c->alloc, sizeof *k);
    if (!k) {
        schedule_retry(c);
        return;
    }
    k->cl = c;
    /* before the WELCOME only it or an ERROR can come: at most SLVP_WELCOME_FIXED + 255 bytes */
    k->rcap = SLVP_LEN_BYTES + SLVP_WELCOME_FIXED + SLVP_METHOD_MAX;
    k->rbuf = net_alloc(c->alloc, k->rcap);
    if (!k->rbuf) {
        net_free(c->alloc, k, sizeof *k);
        schedule_retry(c);
        return;
    }
    uv_tcp_init(&c->loop, &k->tcp);
    k->tcp.data = k;
    k->creq.data = k;
    c->cn = k;
    struct sockaddr_storage addr;
    if (strchr(c->host, ':'))
        uv_ip6_addr(c->host, c->port, (struct sockaddr_in6 *)&addr);
    else
        uv_ip4_addr(c->host, c->port, (struct sockaddr_in *)&addr);
    int rc = uv_tcp_connect(&k->creq, &k->tcp, (const struct sockaddr *)&addr, on_connect);
    if (rc < 0)
        conn_drop(c);
}

static void on_retry(uv_timer_t *t)
{
    sl_vis_client c = t->data;
    try_connect(c);
}

static void schedule_retry(sl_vis_client c)
{
    if (!c->stopping)
        uv_timer_start(&c->retry, on_retry, c->reconnect_ms, 0);
}

static void on_wake(uv_async_t *a)
{
    sl_vis_client c = a->data;
    pthread_mutex_lock(&c->mu);
    bool stop = c->stopping;
    pthread_mutex_unlock(&c->mu);
    if (stop) {
        uv_timer_stop(&c->retry);
        if (c->cn) {
            conn *k = c->cn;
            k->closing = true;
            c->cn = NULL;
            uv_close((uv_handle_t *)&k->tcp, on_conn_closed);
        }
        uv_close((uv_handle_t *)&c->retry, NULL);
        uv_close((uv_handle_t *)&c->wake, NULL);
        return;
    }
    pump(c);
}

static void *client_main(void *arg)
{
    sl_vis_client c = arg;
    try_connect(c);
    uv_run(&c->loop, UV_RUN_DEFAULT);
    return NULL;
}

void sl_vis_client_destroy(sl_vis_client c)
{
    if (!c)
        return;
    if (c->thread_started) {
        pthread_mutex_lock(&c->mu);
        c->stopping = true;
        pthread_mutex_unlock(&c->mu);
        uv_async_send(&c->wake);
        pthread_join(c->thread, NULL);
    }
    uv_loop_close(&c->loop);
    for (int i = 0; i < 3; i++)
        net_free(c->alloc, c->bufs[i].ids, (size_t)c->capacity * sizeof(uint32_t));
    net_free(c->alloc, c->scratch, slvp_scratch_bytes(c->capacity));
    ZSTD_freeDCtx(c->dctx);
    pthread_mutex_destroy(&c->mu);
    pthread_cond_destroy(&c->cv);
    net_free(c->alloc, c, sizeof *c);
}

sl_status sl_vis_client_create(const sl_vis_client_options *o, sl_vis_client *out, sl_error *err)
{
    *out = NULL;
    if (!o || !o->port)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis client: no port");
    const char *host = o->host ? o->host : "127.0.0.1";
    struct sockaddr_storage addr;
    if (strlen(host) >= 64 || (strchr(host, ':') ? uv_ip6_addr(host, o->port, (struct sockaddr_in6 *)&addr)
                                                  : uv_ip4_addr(host, o->port, (struct sockaddr_in *)&addr)) != 0)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis client: host '%s': not an IPv4 or IPv6 address", host);
    sl_camera cam = o->intrinsics;
    if (cam.width == 0 && cam.height == 0 && cam.near_plane == 0)
        cam = sl_camera_default();
    sl_status st = sl_camera_validate(&cam, err);
    if (st != SL_OK)
        return st;
    { /* what the protocol can carry (a server would refuse the HELLO on every connection) */
        uint8_t hb[64];
        slvp_hello h = hello_of(&cam);
        size_t hn = slvp_write_hello(hb, &h);
        char why[192];
        if (!slvp_read_hello(hb + SLVP_LEN_BYTES, hn - SLVP_LEN_BYTES, &h, why, sizeof why))
            return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis client: the camera cannot be sent: %s", why);
    }
    const sl_allocator *a = o->alloc ? o->alloc : sl_default_allocator();
    sl_vis_client c = net_calloc(a, sizeof *c);
    if (!c)
        return net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis client: out of memory");
    c->alloc = a;
    snprintf(c->host, sizeof c->host, "%s", host);
    c->port = o->port;
    c->intrinsics = cam;
    c->reconnect_ms = o->reconnect_ms ? o->reconnect_ms : 100;
    c->expect_objects = o->object_count;
    c->front = 0;
    c->ready = 1;
    c->decode = 2;
    pthread_mutex_init(&c->mu, NULL);
    pthread_cond_init(&c->cv, NULL);
    uv_loop_init(&c->loop);
    uv_async_init(&c->loop, &c->wake, on_wake);
    c->wake.data = c;
    uv_timer_init(&c->loop, &c->retry);
    c->retry.data = c;
    c->dctx = ZSTD_createDCtx();
    if (!c->dctx || net_thread_create(&c->thread, client_main, c) != 0) {
        uv_close((uv_handle_t *)&c->retry, NULL);
        uv_close((uv_handle_t *)&c->wake, NULL);
        uv_run(&c->loop, UV_RUN_DEFAULT);
        sl_vis_client_destroy(c);
        return net_fail(err, SL_ERROR_INTERNAL, "vis client: cannot start its thread");
    }
    c->thread_started = true;
    *out = c;
    return SL_OK;
}

sl_status sl_vis_client_send_view(sl_vis_client c, const sl_camera *cam, float speed, uint32_t *seq, sl_error *err)
{
    const float v[7] = {cam->position.x, cam->position.y, cam->position.z, cam->yaw, cam->pitch, cam->roll, speed};
    for (int i = 0; i < 7; i++)
        if (!isfinite(v[i]))
            return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis client: viewpoint component %d is not finite", i);
    if (speed < 0.0f || speed > SLVP_SPEED_MAX)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis client: speed %g outside [0, 1e4] m/s", (double)speed);
    pthread_mutex_lock(&c->mu);
    slvp_view m = {.seq = ++c->next_seq, .eye = {v[0], v[1], v[2]}, .yaw = v[3], .pitch = v[4], .roll = v[5],
                   .speed = speed};
    c->latest = m;
    c->latest_unsent = true;
    pthread_mutex_unlock(&c->mu);
    if (seq)
        *seq = m.seq;
    uv_async_send(&c->wake);
    return SL_OK;
}

bool sl_vis_client_wait(sl_vis_client c, uint32_t seq, uint32_t timeout_ms)
{
    struct timespec until;
    clock_gettime(CLOCK_REALTIME, &until);
    until.tv_sec += timeout_ms / 1000;
    until.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
    if (until.tv_nsec >= 1000000000L) {
        until.tv_sec++;
        until.tv_nsec -= 1000000000L;
    }
    pthread_mutex_lock(&c->mu);
    while (c->newest_seq < seq)
        if (pthread_cond_timedwait(&c->cv, &c->mu, &until) != 0)
            break;
    bool ok = c->newest_seq >= seq;
    pthread_mutex_unlock(&c->mu);
    return ok;
}

bool sl_vis_client_acquire(sl_vis_client c, sl_vis_set *out)
{
    pthread_mutex_lock(&c->mu);
    bool changed = false;
    if (c->ready_new) {
        int t = c->front;
        c->front = c->ready;
        c->ready = t;
        c->ready_new = false;
        changed = true;
    }
    const set_buffer *f = &c->bufs[c->front];
    *out = (sl_vis_set){.ids = f->ids, .count = f->count, .seq = f->seq, .validity = f->validity,
                        .cell = f->seq ? f->cell : SL_NONE, .received = f->received};
    pthread_mutex_unlock(&c->mu);
    return changed;
}

void sl_vis_client_get_stats(sl_vis_client c, sl_vis_client_stats *out)
{
    pthread_mutex_lock(&c->mu);
    *out = c->stats;
    pthread_mutex_unlock(&c->mu);
}

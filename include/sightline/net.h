/* Sightline network visibility: a server that answers viewpoints with visible sets over TCP, and
 * its client (issue 18, "Instant Visibility" across processes: P. Wonka, PhD thesis, TU Wien 2001,
 * chapter 6). The wire protocol is docs/protocol.md; how to run it, docs/vis-server.md.
 *
 * The server holds one scene, one shared acceleration handle (accel.h) and a small pool of worker
 * threads, each with its own culler of one registered method (cull.h; a method spec
 * "NAME[:OPTIONS]", e.g. "cullmap", "dhorizon", "pvs:file=city.slpvs"). Its event loop (libuv)
 * runs on a thread of its own and never culls: viewpoints go to the workers, a client's newer
 * viewpoint replaces an older one still waiting (coalescing), and a client that reads slowly gets
 * its older unsent sets dropped for newer ones (each client's output queue is bounded, so is its
 * memory: sl_vis_server_stats). With a method whose set holds over a region (pvs: the eye's view
 * cell, for any view direction), every client in that region is answered from one cached set.
 *
 * The client connects, sends its camera's intrinsics once and viewpoints (pose, speed) as often as
 * it likes; sets arrive on its own event-loop thread and are double-buffered: the displayed set
 * changes only in sl_vis_client_acquire, and only to a completely received set. It reconnects by
 * itself after the server goes away (a restart) and resends its latest viewpoint.
 *
 * This layer is optional (libsightline_net, CMake SL_NET=AUTO/ON/OFF, built when libuv is found).
 *
 * Thread safety: sl_vis_server_* calls may come from any thread (one at a time per call of
 * create/destroy; sl_vis_server_port and sl_vis_server_get_stats from any number at once). On a
 * client, sl_vis_client_send_view, sl_vis_client_wait, sl_vis_client_acquire and
 * sl_vis_client_get_stats may be called from any thread, concurrently with each other; the ids that
 * sl_vis_client_acquire returns stay valid until the next sl_vis_client_acquire or destroy.
 * sl_vis_reference is used by one thread at a time (one per thread). The scene must outlive the
 * server and every reference made for it, and must not change while they live.
 *
 * Signals: the threads the server and the client start block SIGPIPE, so that a peer gone in the
 * middle of a write ends that connection (EPIPE) and never the process; the process's signal
 * dispositions and the calling threads' masks are left as they are.
 */
#ifndef SIGHTLINE_NET_H
#define SIGHTLINE_NET_H

#include "core.h"
#include "geom.h"
#include "camera.h"
#include "scene.h"
#include "accel.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The protocol version this library speaks (docs/protocol.md). */
#define SL_VIS_PROTOCOL_VERSION 1u

/* What a received set holds good for. */
typedef enum sl_vis_validity {
    SL_VIS_POINT = 0,  /* the method's set for exactly the viewpoint it answers (its seq) */
    SL_VIS_CELL = 1    /* the set of view cell `cell` of the method's PVS: valid for every eye in
                          the cell, in any view direction, with the same camera intrinsics, whose
                          near-plane reach stays inside the cells (sl_vis_reference_cell says
                          where): a superset of the method's set there */
} sl_vis_validity;

/* ===== the reference: what the server answers for a viewpoint ================================== */

/* The set the server computes for a view, computed in-process: the client's --check, the tests
 * and the bench compare what arrives with it. */
typedef struct sl_vis_reference_t *sl_vis_reference;

/* A reference for method spec `spec` ("NAME[:OPTIONS]") on a scene. reuse: answer eyes in a
 * view cell with the cell's set (methods that have one: pvs); false, always the method's own set.
 * accel may be NULL. alloc may be NULL. */
SL_API sl_status sl_vis_reference_create(sl_scene scene, const char *spec, bool reuse, sl_scene_accel accel,
                                         const sl_allocator *alloc, sl_vis_reference *out, sl_error *err);
SL_API void sl_vis_reference_destroy(sl_vis_reference ref);
/* Whether the method has sets that hold over regions (and reuse was asked for). */
SL_API bool sl_vis_reference_has_regions(sl_vis_reference ref);
/* The set the server sends for camera cam: ids ascending into ids (capacity >= the scene's object
 * count), *validity and *cell (SL_NONE for a point set). */
SL_API sl_status sl_vis_reference_compute(sl_vis_reference ref, const sl_camera *cam, uint32_t *ids, uint32_t capacity,
                                          uint32_t *count, sl_vis_validity *validity, uint32_t *cell, sl_error *err);
/* The method's own set for cam (its culler; never a cell set). */
SL_API sl_status sl_vis_reference_point(sl_vis_reference ref, const sl_camera *cam, uint32_t *ids, uint32_t capacity,
                                        uint32_t *count, sl_error *err);
/* The view cell whose cell set the server answers camera cam with (SL_NONE: a point set). A
 * displayed SL_VIS_CELL set of cell c is valid at cam exactly when this returns c. */
SL_API uint32_t sl_vis_reference_cell(sl_vis_reference ref, const sl_camera *cam);

/* ===== the server ================================================================================ */

typedef struct sl_vis_server_t *sl_vis_server;

/* The largest values sl_vis_server_options takes (sl_vis_server_create refuses more). */
#define SL_VIS_MAX_CLIENTS 65536u
#define SL_VIS_MAX_RATE_HZ 10000u
#define SL_VIS_MAX_QUEUE_SETS 64u
#define SL_VIS_MAX_PIXELS (1u << 28)

/* A zeroed struct gives the defaults. */
typedef struct sl_vis_server_options {
    const char *method;          /* method spec (required): "cullmap", "pvs:file=X.slpvs" */
    const char *host;            /* IPv4 or IPv6 address to listen on; NULL: "127.0.0.1" */
    uint16_t port;               /* 0: a free port (sl_vis_server_port tells which) */
    uint32_t max_clients;        /* connections at once, 1..65536 (default 256); more are refused
                                    with an error message */
    uint32_t workers;            /* culling threads, 1..SL_MAX_THREADS (default 2) */
    uint32_t max_rate_hz;        /* viewpoints per second per client, 1..10000 (default 240; a
                                    burst of one second's worth is allowed); more: an error and
                                    the connection closes */
    uint32_t queue_sets;         /* unsent sets kept per client, 1..64 (default 1); an older one
                                    is dropped for a newer */
    bool no_reuse;               /* never answer from a cached region set */
    uint32_t socket_buffer;      /* bytes of each client socket's kernel send buffer (SO_SNDBUF;
                                    0: the system's; at most 2^30): less kernel queueing in front
                                    of a slow reader, so it gets fresher sets */
    uint32_t max_pixels;         /* width x height a client's HELLO may ask for, 1..2^28 (default
                                    3840 x 2160 = 8,294,400, a 4K frame): the methods that cull at
                                    the client's resolution hold buffers of that size per worker;
                                    more: ERROR code 3 and the connection closes */
    uint32_t hello_timeout_ms;   /* a connection that sends no HELLO within this is refused
                                    (ERROR code 1), so that silent ones cannot hold the
                                    max_clients places; 1..3600000 (default 10000) */
    uint64_t cache_bytes;        /* region-set cache, bytes (default 64 MiB) */
    sl_scene_accel accel;        /* shared acceleration (NULL: the server makes one) */
    const sl_allocator *alloc;   /* NULL: the default allocator */
} sl_vis_server_options;

typedef struct sl_vis_server_stats {
    uint32_t clients;              /* connected now */
    uint64_t clients_total;        /* connections accepted since start (refused ones included) */
    uint64_t clients_refused;      /* beyond max_clients */
    uint64_t views;                /* viewpoints received */
    uint64_t views_coalesced;      /* replaced by a newer one before a worker took them */
    uint64_t sets_sent;            /* sets handed to the socket */
    uint64_t sets_dropped;         /* unsent sets replaced by a newer one (slow readers) */
    uint64_t culls;                /* sets computed by a culler */
    uint64_t cache_hits, cache_misses; /* region sets answered from / added to the cache */
    uint64_t cache_bytes;          /* held by the cache now */
    uint64_t bytes_in, bytes_out;
    uint64_t protocol_errors;      /* connections closed for a malformed message */
    uint64_t rate_limited;         /* connections closed for too many viewpoints */
    uint64_t client_bytes_max;     /* the most memory one client held at any time (its connection
                                      state, buffers and queued sets, shared cached sets excluded) */
    uint64_t client_bytes_bound;   /* what a client can hold at most with these options */
    uint64_t memory_bytes;         /* held by the server now (cache and scene data excluded) */
    double cull_ms_total;          /* worker time computing sets */
} sl_vis_server_stats;

/* Start a server for a scene: listens, and serves on threads of its own until destroyed. */
SL_API sl_status sl_vis_server_create(sl_scene scene, const sl_vis_server_options *options, sl_vis_server *out,
                                      sl_error *err);
/* The port it listens on. */
SL_API uint16_t sl_vis_server_port(sl_vis_server server);
SL_API void sl_vis_server_get_stats(sl_vis_server server, sl_vis_server_stats *out);
/* Stop serving (connections are closed) and release everything. NULL is ignored. */
SL_API void sl_vis_server_destroy(sl_vis_server server);

/* ===== the client ================================================================================ */

typedef struct sl_vis_client_t *sl_vis_client;

typedef struct sl_vis_client_options {
    const char *host;            /* server address; NULL: "127.0.0.1" */
    uint16_t port;               /* required */
    sl_camera intrinsics;        /* projection, fov, near, far, viewport (position and angles ignored);
                                    all zero: sl_camera_default() */
    uint32_t reconnect_ms;       /* wait between connection attempts (default 100) */
    uint32_t object_count;       /* 0: any; else the scene's object count the client expects: a
                                    WELCOME with another is refused before the client reserves
                                    its id buffers (three of object_count ids) */
    const sl_allocator *alloc;
} sl_vis_client_options;

/* The displayed set (sl_vis_client_acquire). */
typedef struct sl_vis_set {
    const uint32_t *ids;         /* ascending; valid until the next acquire */
    uint32_t count;
    uint32_t seq;                /* the viewpoint it answers (0: no set yet) */
    sl_vis_validity validity;
    uint32_t cell;               /* SL_VIS_CELL: the cell; SL_NONE otherwise */
    double received;             /* when it was completely received (CLOCK_MONOTONIC, seconds) */
} sl_vis_set;

typedef struct sl_vis_client_stats {
    bool connected;
    uint32_t object_count;       /* of the server's scene (0 before the first welcome) */
    uint64_t scene_key;          /* sl_pvs_scene_key of the server's scene */
    bool regions;                /* the server answers with cell sets */
    char method[256];            /* the server's method spec */
    uint32_t max_rate_hz;        /* viewpoints a second the server takes from this client (its
                                    WELCOME; 0 before the first): send no faster */
    uint64_t connects;           /* successful connections (reconnects: connects - 1) */
    uint64_t views_sent, sets_received, bytes_in, bytes_out;
    uint64_t errors;             /* connections lost to a bad message or an error from the server */
    char last_error[256];
} sl_vis_client_stats;

/* Start a client: it connects on a thread of its own (and again whenever the connection is lost). */
SL_API sl_status sl_vis_client_create(const sl_vis_client_options *options, sl_vis_client *out, sl_error *err);
/* Send a viewpoint (the pose of cam, the client's speed in m/s); *seq (may be NULL) receives its
 * sequence number (1, 2, ...). While disconnected only the latest is kept and sent on connecting.
 * Refuses a pose that is not finite. */
SL_API sl_status sl_vis_client_send_view(sl_vis_client client, const sl_camera *cam, float speed, uint32_t *seq,
                                         sl_error *err);
/* Wait until a set answering viewpoint seq or a later one has been received (displayed or not),
 * at most timeout_ms; true when it has. */
SL_API bool sl_vis_client_wait(sl_vis_client client, uint32_t seq, uint32_t timeout_ms);
/* Swap in the newest completely received set if it is newer than the displayed one, and return
 * the displayed set (true when it changed). */
SL_API bool sl_vis_client_acquire(sl_vis_client client, sl_vis_set *out);
SL_API void sl_vis_client_get_stats(sl_vis_client client, sl_vis_client_stats *out);
/* Close the connection and release the client. NULL is ignored. */
SL_API void sl_vis_client_destroy(sl_vis_client client);

#ifdef __cplusplus
}
#endif
#endif

/* Sightline draw backends: what a culler that draws (hardware occlusion queries) asks of a renderer.
 *
 * A culler created with a backend (sl_culler_create_with, cull.h) draws the objects it finds
 * visible and asks how many samples of a box, or of some objects, pass the depth test of what it
 * has drawn so far, like an OpenGL renderer with glBeginQuery(GL_SAMPLES_PASSED). It still returns
 * the ascending ids it drew, so the oracle, the bench and the tests judge it as any other method.
 *
 * sl_draw_backend is a table of callbacks plus a user pointer, with no graphics API types: an
 * OpenGL backend implements it with glBeginQuery/glEndQuery on GL_SAMPLES_PASSED (or
 * GL_ANY_SAMPLES_PASSED_CONSERVATIVE), glGetQueryObjectuiv(GL_QUERY_RESULT_AVAILABLE) for `poll`
 * and GL_QUERY_RESULT for `wait`; the library's CPU reference backend (below) implements it with
 * the oracle's reference rasterizer, so query cullers run in CI on any machine.
 *
 * Frames and queries. Between begin_frame and end_frame the culler draws (depth writes) and issues
 * queries: begin_query(q), then query_boxes / query_objects (depth test, no writes) or draw_objects
 * (depth test and writes, as GL counts a query's draws), then end_query. Query objects are created
 * once and reused; a query's result stays readable until it is issued again, across frames, so a
 * culler may read it frames later (coherent hierarchical culling: issue now, read next frame).
 * poll never blocks (ready or not); wait blocks until the result is there and is counted as a
 * stall when it was not ready yet. At most one query is open at a time (GL's rule for one target).
 *
 * Conventions: world_to_clip is column-major float[16] mapping world points to OpenGL clip space
 * (-w <= x, y, z <= w; the matrix of sl_camera_view_proj or of an sl_view), the viewport is
 * width x height pixels. Object ids are those of the scene the backend draws (the culler's scene).
 *
 * Status and errors: every call returns SL_OK or a status with an sl_error message; a culler
 * passes a backend's failure on (prefixed with its name) and the frame fails. A callback must not
 * call back into the culler.
 *
 * Thread safety: a backend is driven by one thread at a time (like a GL context): the culler that
 * uses it, from sl_culler_cull. Two cullers may share one backend only if they never cull at the
 * same time. The table itself is plain data, copied by the culler at creation; `user` must stay
 * valid while a culler holds the table.
 */
#ifndef SIGHTLINE_BACKEND_H
#define SIGHTLINE_BACKEND_H

#include "core.h"
#include "geom.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A query object: a name handed out by create_queries (as glGenQueries hands out GLuints). */
typedef uint32_t sl_draw_query;

/* The version of the table below; a backend sets sl_draw_backend.version to it. */
#define SL_DRAW_BACKEND_VERSION 1u

typedef struct sl_draw_backend {
    uint32_t version; /* SL_DRAW_BACKEND_VERSION */
    void *user;       /* passed to every callback */

    /* Start a frame: clear depth, set the view. world_to_clip: column-major, OpenGL clip space. */
    sl_status (*begin_frame)(void *user, const float world_to_clip[16], uint32_t width, uint32_t height,
                             sl_error *err);
    /* Draw objects (their meshes, transforms and facing rules from the scene) with depth test and
     * depth writes. Inside an open query their passing samples count too. */
    sl_status (*draw_objects)(void *user, const uint32_t *ids, uint32_t count, sl_error *err);
    /* Create `count` query objects, writing their names to out; destroy releases them (a name
     * not created is ignored). */
    sl_status (*create_queries)(void *user, uint32_t count, sl_draw_query *out, sl_error *err);
    void (*destroy_queries)(void *user, const sl_draw_query *queries, uint32_t count);
    /* Open query q (none may be open); its previous result is dropped. */
    sl_status (*begin_query)(void *user, sl_draw_query q, sl_error *err);
    /* Draw boxes (their 12 triangles each, both facings) or objects with depth test and no writes,
     * counted by the open query. */
    sl_status (*query_boxes)(void *user, const sl_aabb *boxes, uint32_t count, sl_error *err);
    sl_status (*query_objects)(void *user, const uint32_t *ids, uint32_t count, sl_error *err);
    /* Close the open query: its result becomes available some time later. */
    sl_status (*end_query)(void *user, sl_error *err);
    /* Non-blocking: *ready tells whether the result of q is available, and then *samples holds the
     * number of samples that passed. A query never issued is an error. */
    sl_status (*poll_query)(void *user, sl_draw_query q, bool *ready, uint64_t *samples, sl_error *err);
    /* Blocking: wait for the result of q (a stall when it was not ready) and return it. */
    sl_status (*wait_query)(void *user, sl_draw_query q, uint64_t *samples, sl_error *err);
    /* End the frame (a GL backend flushes; the CPU backend advances its latency clock). */
    sl_status (*end_frame)(void *user, sl_error *err);
} sl_draw_backend;

/* Check a table: the version and every callback present. SL_ERROR_INVALID_ARGUMENT naming the
 * first missing one. Pure, thread-safe. */
SL_API sl_status sl_draw_backend_check(const sl_draw_backend *backend, sl_error *err);

/* ===== the CPU reference backend =================================================================
 * Draws objects with the oracle's reference rasterizer (exact integer coverage of pixel centres,
 * the top-left rule, the oracle's depth (1 - z/w)/2 evaluated per pixel in double and stored as
 * float, the oracle's facing rule: closed convex objects without their back faces), so the depth
 * buffer after drawing a set of objects is exactly the oracle's buffer for that set at the same
 * resolution. A query counts fragments: every fragment of the query's triangles that is at least
 * as near as the stored depth (glDepthFunc(GL_LEQUAL) in the standard depth order), one sample per
 * pixel at its centre, overlaps counted twice, as GL_SAMPLES_PASSED counts. Counts are exact and
 * deterministic (a pure function of the scene, the view and the calls).
 *
 * Latency: a query ended in frame k (the k-th begin_frame, from 0) is ready for poll from frame
 * k + latency_frames on (latency 0: at once). wait returns it at any time and, when it was not ready
 * yet, counts a stall and makes it ready. The result is computed when the query ends (against the
 * depth at that moment, as a GPU would), only its availability is delayed.
 *
 * The simulated clock (the time fields of the options; all 0: off, and the above is all). A
 * deterministic model of a GPU that runs in step with the calls: each draw_objects call and each
 * query adds ns_per_call, each triangle drawn or queried (a box: 12) ns_per_triangle, each fragment
 * that passes (written by a draw, counted by a query) ns_per_fragment to the clock; frame k begins
 * at max(clock, k * frame_ns). A query ended at clock t is ready for poll once the clock reaches
 * t + query_latency_ns (and the frame rule above holds). poll costs nothing; a wait on a result that
 * is not ready moves the clock to its ready time: a stall, and the time moved is wait time
 * (sl_draw_backend_cpu_stats.wait_ns). So the sets and every counter are the same run to run, and
 * a culler that waits at once (stop and wait) pays the latency per query, one that keeps drawing
 * while queries are in flight (CHC) finds them ready.
 *
 * Thread safety: one thread at a time per backend (any call, the table's callbacks included);
 * distinct CPU backends on one scene run in parallel while the scene does not change. */

typedef struct sl_draw_backend_cpu_t *sl_draw_backend_cpu;

typedef struct sl_draw_backend_cpu_options {
    uint32_t latency_frames; /* frames until a query's result is ready for poll; 0: at once; at most 64 */
    /* The simulated clock (above), in simulated nanoseconds; each finite, 0..1e12; all 0: off.
     * Appended (issue 15): a zeroed struct keeps the behaviour before it. */
    double ns_per_call;      /* a draw_objects call, a query (begin_query..end_query) */
    double ns_per_triangle;  /* a triangle drawn or queried (a box: 12) */
    double ns_per_fragment;  /* a fragment that passes: written by a draw, counted by a query */
    double query_latency_ns; /* from a query's end until its result is ready for poll */
    double frame_ns;         /* frame k begins no earlier than k * frame_ns */
} sl_draw_backend_cpu_options;

/* The clock of sl_culler's query methods' own CPU backends (docs/query-culling.md): 2 us a call,
 * 2 ns a triangle, 0.05 ns a fragment, a 20 us query latency, 33.3 ms frames (30 fps). */
SL_API sl_draw_backend_cpu_options sl_draw_backend_cpu_clock_default(void);

/* Counters since creation or the last reset. */
typedef struct sl_draw_backend_cpu_stats {
    uint64_t frames;          /* begin_frame calls */
    uint64_t draw_calls;      /* draw_objects calls */
    uint64_t objects_drawn;
    uint64_t triangles_drawn; /* triangles of the objects drawn (before clipping) */
    uint64_t queries;         /* queries issued (begin_query) */
    uint64_t query_boxes;     /* boxes drawn by queries */
    uint64_t query_objects;   /* objects drawn by queries */
    uint64_t query_triangles; /* triangles drawn by queries (12 a box) */
    uint64_t samples_passed;  /* sum of the query results */
    uint64_t polls, polls_not_ready;
    uint64_t waits, stalls;   /* wait calls; those that found the result not ready */
    /* the simulated clock (appended, issue 15; 0 with the clock off) */
    double clock_ns;          /* the clock now (not reset by reset_stats) */
    double busy_ns;           /* time added by draws and queries */
    double wait_ns;           /* time added by waits on results not ready (stalls) */
} sl_draw_backend_cpu_stats;

/* Create a CPU backend for a scene (which must outlive it and keep its objects). options and alloc
 * may be NULL (latency 0; the default allocator). The depth buffer is sized at begin_frame. */
SL_API sl_status sl_draw_backend_cpu_create(sl_scene scene, const sl_draw_backend_cpu_options *options,
                                            const sl_allocator *alloc, sl_draw_backend_cpu *out, sl_error *err);
/* Release it. NULL is ignored. */
SL_API void sl_draw_backend_cpu_destroy(sl_draw_backend_cpu cpu);
/* The table to create a culler with (user = cpu); valid while cpu lives. */
SL_API sl_draw_backend sl_draw_backend_cpu_table(sl_draw_backend_cpu cpu);
/* The CPU backend behind a table made by sl_draw_backend_cpu_table, NULL for any other table (so
 * that a culler reads its simulated clock). */
SL_API sl_draw_backend_cpu sl_draw_backend_cpu_of(const sl_draw_backend *table);
/* Counters; reset sets them to zero. */
SL_API void sl_draw_backend_cpu_get_stats(sl_draw_backend_cpu cpu, sl_draw_backend_cpu_stats *out);
SL_API void sl_draw_backend_cpu_reset_stats(sl_draw_backend_cpu cpu);
/* The current frame's depth buffer (width*height floats, row 0 at the top, 0 where nothing was
 * drawn) and ids (SL_NONE where nothing was drawn), e.g. for tests; any pointer may be NULL.
 * Valid until the next begin_frame or destroy. */
SL_API void sl_draw_backend_cpu_buffers(sl_draw_backend_cpu cpu, const float **depth, const uint32_t **ids,
                                        uint32_t *width, uint32_t *height);
/* Bytes held: the buffers and query slots exactly, the vertex scratch approximately. */
SL_API size_t sl_draw_backend_cpu_memory(sl_draw_backend_cpu cpu);

#ifdef __cplusplus
}
#endif
#endif

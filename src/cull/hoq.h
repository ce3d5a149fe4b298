/* The query box of the hoq method (hoq.c), apart so that tests/test_backend.c can check it: every
 * pixel centre an object covers at the culling resolution, the grown box covers at least as near. */
#ifndef SL_CULL_HOQ_H
#define SL_CULL_HOQ_H

#include "core/sl_core.h"
#include "sightline/geom.h"
#include "sightline/backend.h"
#include "cull/culler_internal.h"

/* What the query box needs of a view. */
typedef struct sl_hoq_view {
    double vp[16];      /* world to clip, the float matrix in double (as the backend converts it) */
    float eye[3];
    double footprint;   /* a pixel's width in world units: per unit of distance (perspective), or
                           absolute (ortho) */
    bool ortho;
    float margin;       /* pixels */
    bool reach;         /* the reach toward the eye (below); true from sl_hoq_view_set, false in a
                           test measuring the margin alone */
} sl_hoq_view;

/* From a view: the float world-to-clip and projection matrices (column-major, OpenGL), the viewport
 * and the eye. The pixel's width is the larger of the two axes' 2 / (scale * pixels). */
void sl_hoq_view_set(sl_hoq_view *v, const sl_mat4 *view_proj, const sl_mat4 *proj, uint32_t width, uint32_t height,
                     sl_vec3 eye, bool ortho, float margin);

/* The query box of a node with box b, into *g: b grown by margin pixel footprints at its farthest
 * corner (and by the float rounding of its coordinates), then given its reach toward the eye:
 * moved along the view rays (scaled about the eye in perspective) until its farthest point is as
 * near as its nearest one was; it keeps the grown box's footprint on screen. False when the query box reaches behind the near plane or holds the eye (it
 * must count as visible unqueried).
 *
 * Why the reach (the depth bound). The reference rasterizer covers pixel centres by the snapped
 * vertices (1/256 pixel) but takes depth from the plane through the exact ones, clamped to the
 * triangle's vertex range (raster_ref.h). A centre p the snapped triangle T covers lies within
 * 1/512 pixel (each axis) of T's exact projection, at the point q* with the same barycentric
 * weights, and p's depth is d(q*) + grad(d).(p - q*), clamped: the error grad(d).(p - q*) has no
 * bound but the clamp, since a triangle seen edge-on has an unbounded screen-space depth gradient
 * (test_hoq_box_covers measures one: a ground polygon under a degree, the fragment 0.1 % nearer
 * than the grown box at a pixel on the horizon). So the one bound is the clamp: no fragment of a
 * triangle inside b is nearer than b's nearest corner, and it lies within 1/512 pixel of b's
 * projection. The query box lies, on every view ray through the grown box's footprint, at least
 * as near as that corner, and that footprint covers b's projection
 * with the margin to spare (against both snappings), so its rasterized front is at least as near
 * as any fragment of b's triangles at every pixel they cover. */
bool sl_hoq_grow_box(const sl_hoq_view *v, const sl_aabb *b, sl_aabb *g);

/* ---- what the query cullers share (gl-stopwait here, chc and chc++ in chc.c) ----
 * The backend: the one given (sl_cull_extras.backend), or a CPU reference backend of their own
 * with `latency` frames and, with `clock` (default), the simulated clock of
 * sl_draw_backend_cpu_clock_default with its query latency set by query_latency_us. */
typedef struct sl_qc_backend_opts {
    uint32_t latency;        /* frames */
    bool clock;
    float query_latency_us;
} sl_qc_backend_opts;

/* The options' help lines of the backend options, and their reader (configure). */
#define SL_QC_BACKEND_HELP                                                                                            \
    "latency=0..64 (default 0): frames until a query result is ready, of the CPU backend it makes when given none "  \
    "(a wait before that is a stall)\n"                                                                               \
    "clock=BOOL (default true): that backend's simulated clock (docs/query-culling.md: 2 us a call, 2 ns a "          \
    "triangle, 0.05 ns a fragment, 30 fps frames), which makes results wait for their latency\n"                     \
    "query_latency_us=0..100000 (default 20): the clock's query latency, simulated microseconds\n"
sl_status sl_qc_backend_configure(sl_opts *o, sl_qc_backend_opts *c, sl_error *err);

typedef struct sl_qc_backend {
    sl_draw_backend be;
    sl_draw_backend_cpu own;    /* the backend of its own, or NULL */
    sl_draw_backend_cpu cpu;    /* the CPU backend behind `be` (own or given), or NULL */
    double wait_ns0;            /* its wait time at the frame's start */
    double wall_wait_ms;        /* wall time inside wait_query this frame (other backends) */
} sl_qc_backend;

/* Open it (a given backend with non-default backend options is refused, naming them). */
sl_status sl_qc_backend_open(sl_qc_backend *q, sl_scene scene, const sl_qc_backend_opts *c, const sl_cull_extras *extras,
                             const sl_allocator *alloc, sl_error *err);
void sl_qc_backend_close(sl_qc_backend *q);
/* Frame bracket of the wait time: start sets the counters, wait_ms reads the frame's wait (the CPU
 * backend's simulated wait time, else the wall time inside wait_query). */
void sl_qc_frame_start(sl_qc_backend *q);
double sl_qc_wait_ms(const sl_qc_backend *q);
/* wait_query, timed. */
sl_status sl_qc_wait(sl_qc_backend *q, sl_draw_query query, uint64_t *samples, sl_error *err);

#endif

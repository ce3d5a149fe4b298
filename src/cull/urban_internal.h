/* Shared machinery of the urban 2.5D cullers (cullmap, horizon, dhorizon) and of the radar echo
 * generator: occluder extraction from building footprints, the view analysis (eye, azimuth range
 * of the frustum, its ground footprint, near-plane guard), the max-height pyramid over the scene
 * grid, the polar occlusion horizon, and the front-to-back horizon sweep.
 *
 * Occluders. Each footprint edge is a façade whose top edge is an occluder edge (Wonka §4.2.1);
 * it is valid when its footprint's prism lies inside the building object it stands for (so that
 * any sight line entering the prism has crossed the rendered building first) and it has length.
 * Footprints without an object are trusted to be solid. Per frame an edge is usable when it faces
 * the eye (roof above the eye: front-facing edges; roof at or below the eye: back-facing ones, which
 * form the silhouette seen from above), is farther than the near-plane guard (a nearer façade
 * could be clipped away by the near plane and seen through), and its building does not contain
 * the eye (from inside a building its walls hide nothing). Consecutive usable edges of one
 * footprint, and of footprints sharing a vertex exactly (a row of buildings with party walls),
 * form silhouette chains; the cull map closes the seams along them.
 *
 * The horizon (Downs et al. 2001; Koldaş 2008 §3.1.2) is a piecewise-constant elevation over
 * azimuth, in N equal bins over [0, 2*pi), kept in a complete binary tree with the minimum and
 * maximum per node (azimuths as pseudo-azimuths and elevations as slopes, see sl_urban_paz, so that
 * no trigonometry is needed). Bin k holds H[k], a lower bound of the elevation below which everything behind
 * the occluders inserted so far is hidden for every azimuth of the bin, and B[k], an upper bound
 * of the bottom elevation of the occluder that set H[k] (a sight line below a façade's base is not
 * blocked by it). An occluder covering only part of a bin is remembered per bin as a left part
 * [bin start, x] or a right part [x, bin end]; when the two meet the bin takes the smaller value.
 * So contiguous façades or terrain edges leave no crack between them; the 0/2*pi wrap is a bin
 * boundary. */
#ifndef SL_CULL_URBAN_INTERNAL_H
#define SL_CULL_URBAN_INTERNAL_H

#include "culler_internal.h"

#include "accel/grid_internal.h"
#include "raster/cullmap_raster.h"
#include "scene/scene_internal.h"

#include <math.h>

#define SL_URBAN_TWO_PI 6.283185307179586476925286766559
/* The full circle in pseudo-azimuth units (see sl_urban_paz). */
#define SL_URBAN_CIRCLE 4.0

typedef struct sl_urban_view sl_urban_view;

/* ===== occluders from footprints ================================================================ */

typedef struct sl_urban_edge {
    float ax, ay, bx, by;       /* top edge a->b in the footprint's CCW order (outside on the right) */
    uint32_t fp;                /* footprint */
    uint32_t next, prev;        /* neighbours in the same footprint */
    uint32_t alt_next[2];       /* edges of other footprints starting exactly at b (SL_NONE: none) */
    uint32_t alt_prev[2];       /* edges of other footprints ending exactly at a */
    uint32_t cell_first, cell_count; /* cells it passes through (edge_cells) */
} sl_urban_edge;

typedef struct sl_urban_fp {
    uint32_t object;            /* building object, or SL_NONE */
    uint32_t first_edge, edge_count;
    float roof, base;
    sl_aabb box;                /* prism box, grown to the object's box: the eye inside excludes it */
    bool valid;
} sl_urban_fp;

/* A piece of an edge inside one grid cell (the horizon inserts occluders cell by cell). */
typedef struct sl_urban_piece {
    float x0, y0, x1, y1;
    uint32_t edge;
} sl_urban_piece;

/* Everything the urban cullers derive from a scene once. */
typedef struct sl_urban_scene {
    sl_allocator alloc;
    sl_scene scene;
    sl_grid grid;
    uint32_t nx, ny, ncells;
    double min_x, min_y, cell, margin;  /* margin: rounding allowance on every cell rectangle */
    float *cell_floor;          /* per cell: lowest object box bottom (INFINITY when empty) */
    float *cell_top;            /* per cell: highest object box top or roof (-INFINITY when empty) */
    float *node_floor;          /* per cell, grown by the footprint bases of the pieces (horizon) */

    uint32_t fp_count;
    sl_urban_fp *fps;
    uint32_t edge_count;
    sl_urban_edge *edges;
    uint32_t *edge_cells;       /* cell indices, per edge a range */
    size_t edge_cell_total;
    uint32_t *cell_edge_start;  /* ncells+1: edges passing through each cell */
    uint32_t *cell_edges;
    uint32_t *cell_fp_start;    /* ncells+1: footprints whose box overlaps each cell */
    uint32_t *cell_fps;
    uint32_t *cell_piece_start; /* ncells+1: pieces of each cell */
    sl_urban_piece *pieces;
    uint32_t piece_count;

    /* max-height pyramid: level 0 = the cells; node ids are level_base[l] + j*level_nx[l] + i */
    uint32_t levels;
    uint32_t level_nx[32], level_ny[32], level_base[32];
    uint32_t node_count;
    float *pyr_top, *pyr_floor;

    uint32_t object_count;
    sl_aabb *boxes;             /* copy of the object boxes the structures were built from */
    uint32_t *footprint_of;     /* per object: its first footprint or SL_NONE */
    uint32_t *outside;          /* objects not wholly inside the grid (moved out): always tested */
    uint32_t outside_count;
    double world[2][3];         /* box of everything the methods read: object boxes, the grid, the
                                   footprints' heights (bounds the far plane, sl_urban_view_make) */
    size_t memory;
} sl_urban_scene;

/* Build the grid (cell size in metres), the occluder edges, per-cell lists, pieces and pyramid. */
sl_status sl_urban_scene_build(sl_scene scene, float cell, const sl_allocator *alloc, sl_urban_scene *out,
                               sl_error *err);
/* Objects moved: update the grid, the per-cell heights, the pyramid and the footprints' validity. */
sl_status sl_urban_scene_refresh(sl_urban_scene *u, sl_error *err);
/* The `applicable` hook of the 2.5D methods (sl_cull_method_applicable): false, with why, when the
 * scene has no building footprint (config unused). */
bool sl_urban_applicable(sl_scene scene, const void *config, char *why, size_t why_size);
void sl_urban_scene_free(sl_urban_scene *u);
/* Report the objects that left the grid and meet the frustum (stamp: once per frame). */
void sl_urban_add_outside(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *stamp, uint32_t frame,
                          uint32_t *out, uint32_t *n);

/* ===== the view ================================================================================= */

#define SL_URBAN_MAX_POLY 16

struct sl_urban_view {
    bool perspective;
    double eye[3];
    double forward[3];
    bool full_az;               /* the frustum reaches straight up or down: every azimuth */
    double az0, az_span;        /* else the azimuths [az0, az0 + az_span], az0 in [0, 2*pi) */
    double paz0, paz_span;      /* the same range in pseudo-azimuth units */
    double cone[2][3];          /* the two boundary half-planes of that range: a*x + b*y + c >= 0 */
    double near_guard;          /* occluders nearer (in plan) than this are not used */
    double far;                 /* farthest distance of anything in the frustum */
    sl_plane planes[6];
    float slack[6];
    double poly[SL_URBAN_MAX_POLY][2]; /* the frustum's ground plan (convex, CCW, slightly grown) */
    int npoly;
};

/* Analyse a (validated) camera. */
/* The view of a camera. Its far plane is first brought in to just beyond the farthest point of
 * u->world (when nearer than the camera's): the frustum's plan polygon is the hull of its
 * corners, whose double-precision orientation tests lose a near corner once the far corners lie
 * 1e17 m away or more, and the azimuth range comes from the float far corners (far 1e20 m missed
 * objects); everything the methods can cull lies within that
 * distance, so the result is the same as with the camera's far plane. */
void sl_urban_view_make(const sl_urban_scene *u, const sl_view *view, sl_urban_view *v);
/* Box against the frustum planes (with the rounding slack of vfc): false only when outside. */
bool sl_urban_box_in_frustum(const sl_urban_view *v, const sl_aabb *b);

/* Inclusive cell spans, per row, of every cell the frustum's ground plan touches: rows *j0..*j1,
 * x0[j - j0]..x1[j - j0] (arrays of ny entries); false when none. */
bool sl_urban_frustum_spans(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *j0, uint32_t *j1, int32_t *x0,
                            int32_t *x1);

/* Mark (stamp[fp] = frame) the footprints whose building contains the eye or is within the near
 * guard of it: they hide nothing this frame. */
void sl_urban_exclude(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *stamp, uint32_t frame);

/* How edge e serves as an occluder this frame: +1 used as given (a->b), -1 reversed (b->a), 0 not
 * at all. excluded: footprint stamps of sl_urban_exclude. */
int sl_urban_edge_mode(const sl_urban_scene *u, uint32_t e, const sl_urban_view *v, const uint32_t *excluded,
                       uint32_t frame);

/* Per-frame memo of sl_urban_edge_mode (arrays of edge_count entries, zeroed at creation). */
typedef struct sl_urban_mode_cache {
    uint32_t *frame;
    int8_t *mode;
} sl_urban_mode_cache;

/* sl_urban_edge_mode through the memo (cache may be NULL). */
static inline int sl_urban_edge_mode_cached(const sl_urban_scene *u, uint32_t e, const sl_urban_view *v,
                                            const uint32_t *excluded, uint32_t frame, const sl_urban_mode_cache *cache)
{
    if (!cache)
        return sl_urban_edge_mode(u, e, v, excluded, frame);
    if (cache->frame[e] != frame) {
        cache->frame[e] = frame;
        cache->mode[e] = (int8_t)sl_urban_edge_mode(u, e, v, excluded, frame);
    }
    return cache->mode[e];
}

/* The oriented shadow edge of e for mode +1/-1. */
sl_shadow_edge sl_urban_shadow_edge(const sl_urban_scene *u, uint32_t e, int mode);

/* The usable edge continuing e's chain after (dir = +1) or before (dir = -1) it, for e used in
 * mode; SL_NONE at a silhouette end. */
uint32_t sl_urban_chain_step(const sl_urban_scene *u, uint32_t e, int mode, int dir, const sl_urban_view *v,
                             const uint32_t *excluded, uint32_t frame, const sl_urban_mode_cache *cache);

/* Plan distance from the eye to segment (x0,y0)-(x1,y1). */
double sl_urban_seg_dist(const sl_urban_view *v, double x0, double y0, double x1, double y1);

/* fmin/fmax without the libm call (they are not inlined without -ffast-math), with their NaN rule:
 * a NaN argument yields the other one. */
static inline float sl_urban_minf(float a, float b) { return (b < a || a != a) ? b : a; }
static inline float sl_urban_maxf(float a, float b) { return (b > a || a != a) ? b : a; }
static inline double sl_urban_min(double a, double b) { return (b < a || a != a) ? b : a; }
static inline double sl_urban_max(double a, double b) { return (b > a || a != a) ? b : a; }

/* ===== polar helpers ============================================================================ */

/* Pseudo-azimuth (the "diamond angle") of direction (dx, dy): a strictly increasing function of
 * the azimuth measured counter-clockwise from +x, with values in [0, 4) (0, 1, 2, 3 at +x, +y, -x,
 * -y), free of trigonometry. The horizon's bins are equal steps of it; since every test compares
 * pseudo-azimuths of directions with pseudo-azimuths of directions, the guarantees carry over. */
static inline double sl_urban_paz(double dx, double dy)
{
    if (dy >= 0)
        return dx >= 0 ? (dx + dy > 0 ? dy / (dx + dy) : 0.0) : 1.0 + -dx / (dy - dx);
    return dx < 0 ? 2.0 + -dy / (-dx - dy) : 3.0 + dx / (dx - dy);
}
/* A direction (not normalized) with pseudo-azimuth p (in [0, 4]). */
static inline void sl_urban_paz_dir(double p, double *dx, double *dy)
{
    double q = floor(p), f = p - q;
    switch ((int)q & 3) {
    case 0: *dx = 1.0 - f, *dy = f; break;
    case 1: *dx = -f, *dy = 1.0 - f; break;
    case 2: *dx = f - 1.0, *dy = -f; break;
    default: *dx = f, *dy = f - 1.0; break;
    }
}
/* p wrapped into [0, 4). */
static inline double sl_urban_paz_wrap(double p)
{
    if (!(p >= -SL_URBAN_CIRCLE && p < 2 * SL_URBAN_CIRCLE)) /* (sums and differences stay within) */
        p = fmod(p, SL_URBAN_CIRCLE);
    else if (p >= SL_URBAN_CIRCLE)
        p -= SL_URBAN_CIRCLE; /* exact, as fmod */
    if (p < 0)
        p += SL_URBAN_CIRCLE;
    return p >= SL_URBAN_CIRCLE ? 0.0 : p;
}

/* Pseudo-azimuth range of a rectangle seen from the eye: [*a0, *a0 + *span]; false (full circle,
 * *span = 4) when the eye is within the rectangle. */
bool sl_urban_rect_az(const double eye[3], double x0, double y0, double x1, double y1, double *a0, double *span);
/* Nearest and farthest plan distances from the eye to a rectangle. */
void sl_urban_rect_dist(const double eye[3], double x0, double y0, double x1, double y1, double *dmin, double *dmax);
/* Elevations are kept as slopes (tangents: height over plan distance), which order like angles.
 * Upper bound of the slope of anything at most z high at plan distances [dmin, dmax], and lower
 * bound of the slope of anything at least z high there. */
static inline double sl_urban_slope_hi(double z, double ez, double dmin, double dmax)
{
    double h = z - ez;
    return h > 0 ? h / dmin : (h < 0 ? h / dmax : 0.0);
}
static inline double sl_urban_slope_lo(double z, double ez, double dmin, double dmax)
{
    double h = z - ez;
    return h < 0 ? h / dmin : (h > 0 ? h / dmax : 0.0);
}
/* Does pseudo-azimuth range [a0, a0+span] (span >= 4: all) meet the view's range? */
bool sl_urban_az_meets(const sl_urban_view *v, double a0, double span);

/* ===== the horizon ============================================================================== */

typedef struct sl_horizon {
    sl_allocator alloc;
    uint32_t n;                 /* bins, a power of two */
    double binw;                /* 4 / n (pseudo-azimuth) */
    float *hmin, *hmax, *hbot;  /* 2n tree nodes, leaves at n..2n-1: min, max of H; max of B
                                   (slopes; -INFINITY: nothing) */
    double *lx, *rx;            /* per bin: end of the left part, start of the right part */
    float *lv, *lb, *rv, *rb;   /* their values and bottoms */
    uint64_t bins_written;
    /* history (dhorizon): per bin up to SL_HORIZON_STEPS raises (distance, value), so that the
     * horizon as it stood when the sweep reached distance d can be bounded from above later */
    bool record;
    float key;                  /* sweep distance of the occluder being inserted */
    uint8_t *hist_n;
    float *hist_d, *hist_v;
} sl_horizon;

#define SL_HORIZON_STEPS 4

/* An occluder segment for the horizon: plan endpoints, top height at each end (linear between),
 * bottom height (façade base; -INFINITY: solid below, as terrain). */
typedef struct sl_horizon_seg {
    double ax, ay, az, bx, by, bz;
    double base;
} sl_horizon_seg;

sl_status sl_horizon_init(sl_horizon *h, uint32_t bins, bool record, const sl_allocator *alloc, sl_error *err);
void sl_horizon_free(sl_horizon *h);
/* Nothing hidden: H = below -pi/2 everywhere, no partial coverage. */
void sl_horizon_reset(sl_horizon *h);
/* Insert the shadow of a segment seen from eye (raise H where it covers whole bins or closes a
 * bin with an earlier part). */
void sl_horizon_insert(sl_horizon *h, const double eye[3], const sl_horizon_seg *s);
/* True when every bin meeting [a0, a0+span] (span >= 4: all bins) has H > top and B <= bottom:
 * anything in that azimuth range whose elevations lie in [bottom, top], behind every inserted
 * occluder, is hidden. */
bool sl_horizon_occluded(const sl_horizon *h, double a0, double span, double top, double bottom);
/* Largest H over the bins meeting [a0, a0+span]. */
double sl_horizon_max(const sl_horizon *h, double a0, double span);
/* Upper bound of the largest H over the bins meeting [a0, a0+span] as it stood when the sweep had
 * inserted the occluders up to distance d (history kept); +INFINITY when the range has more than
 * max_bins bins. */
double sl_horizon_max_before(const sl_horizon *h, double a0, double span, double d, uint32_t max_bins);
/* Smallest H and largest B over the bins meeting [a0, a0+span]. */
void sl_horizon_range(const sl_horizon *h, double a0, double span, double *min_h, double *max_b);

/* ===== heaps ==================================================================================== */

typedef struct sl_urban_heap {
    uint32_t n, cap;
    float *key;
    uint32_t *val;
} sl_urban_heap;

sl_status sl_urban_heap_init(sl_urban_heap *h, uint32_t cap, const sl_allocator *a, sl_error *err);
void sl_urban_heap_free(sl_urban_heap *h, const sl_allocator *a);
/* Push (the capacity is never exceeded by the sweeps: each entry is pushed once per frame). */
void sl_urban_heap_push(sl_urban_heap *h, float key, uint32_t val);
/* Make a heap of the n entries stored in key[0..n), val[0..n) in any order (in linear time). */
void sl_urban_heap_build(sl_urban_heap *h);
/* Pop the smallest key. */
uint32_t sl_urban_heap_pop(sl_urban_heap *h);

/* ===== the horizon sweep (horizon and dhorizon) ================================================== */

/* State of a horizon culler; dhorizon adds its incremental bookkeeping. */
typedef struct sl_urban_sweep {
    sl_allocator alloc;
    sl_urban_scene us;
    sl_horizon hz[2];           /* current and previous frame's horizon (dhorizon) */
    uint32_t cur;               /* index of the current one */
    sl_urban_heap nodes, pieces;
    uint32_t frame;
    uint32_t *obj_stamp;        /* per object: frame when decided (visible or hidden whole) */
    uint32_t *fp_excluded;      /* per footprint: frame when excluded */
    sl_urban_mode_cache modes;  /* per edge: how it serves this frame */
    /* the frontier of the last sweep (dhorizon): the nodes where it stopped, each with how (see
     * SL_FRONT_*), tiling the grid less its empty nodes; front[cur] is being written, front[cur ^ 1]
     * is the last one */
    uint32_t *front[2];
    uint32_t front_count[2];
    uint32_t *sort_scratch;
    int32_t *span_x0, *span_x1; /* ny entries: frustum spans (orthographic fallback) */
    /* dhorizon */
    bool incremental;           /* use the previous frame */
    bool parallax;              /* widen the skip test by the parallax bound (conservative) */
    float max_move, max_turn;   /* guard: beyond these, a full sweep */
    uint32_t refresh;           /* a full sweep at least every this many frames (0: never) */
    uint32_t since_full;
    bool have_prev;
    sl_urban_view prev_view;
    /* per-frame counters */
    uint64_t nodes_visited, occlusion_tests, objects_tested, skipped, pixels_written;
} sl_urban_sweep;

/* record: keep the horizon's history (dhorizon). */
sl_status sl_urban_sweep_create(sl_scene scene, float cell, uint32_t bins, bool record, const sl_allocator *alloc,
                                sl_urban_sweep **out, sl_error *err);
void sl_urban_sweep_destroy(sl_urban_sweep *s);
/* One frame: the ascending ids of the objects that may be visible. */
sl_status sl_urban_sweep_cull(sl_urban_sweep *s, const sl_view *view, uint32_t *out, uint32_t *count,
                              sl_cull_stats *stats, sl_error *err);
/* How the sweep left a node (the frontier entry's kind, in the top two bits of the entry). */
enum {
    SL_FRONT_OUT = 0,     /* not looked at: outside the azimuth range, beyond the far plane, empty */
    SL_FRONT_HIDDEN = 1,  /* below the horizon (culled, or skipped by dhorizon): hidden that frame */
    SL_FRONT_VISIBLE = 3  /* a grid cell that was processed (in front of the horizon) */
};
#define SL_FRONT_ENTRY(id, kind) ((id) | ((uint32_t)(kind) << 30))
#define SL_FRONT_ID(e) ((e) & 0x3FFFFFFFu)
#define SL_FRONT_KIND(e) ((e) >> 30)

/* dhorizon (dhorizon.c): may this frame reuse the previous one (the guard)? */
bool sl_dhorizon_prepare(sl_urban_sweep *s, const sl_urban_view *v);
/* dhorizon: may node id, which failed the ordinary test and was hidden last frame, be skipped because
 * the horizon has not dropped there by more than the motion allows?
 * dmin, dmax: its plan distances; [a0, a0+span]: its pseudo-azimuths; lo: the lower bound of its
 * slopes. */
bool sl_dhorizon_skip(sl_urban_sweep *s, const sl_urban_view *v, uint32_t id, double dmin, double dmax, double a0,
                      double span, double lo);
/* The horizon method's scene_changed and destroy, shared with dhorizon. */
sl_status sl_urban_horizon_scene_changed(void *state, sl_error *err);
void sl_urban_horizon_destroy(void *state);

/* Frustum-only fallback for cameras without an eye point (orthographic): every object in a cell of
 * the frustum's plan whose box meets the frustum. Uses obj_stamp/frame of the caller. */
uint32_t sl_urban_frustum_only(const sl_urban_scene *u, const sl_urban_view *v, uint32_t *stamp, uint32_t frame,
                               int32_t *x0, int32_t *x1, uint32_t *out, uint64_t *cells, uint64_t *tested);

#endif

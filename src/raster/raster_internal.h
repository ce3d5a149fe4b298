/* Internals of the software occlusion rasterizer shared by the context code (raster.c), the
 * front end (raster_setup.c), the bins and pool (raster_bins.c) and the per-instruction-set kernels
 * (raster_scalar.c, raster_sse41.c, raster_avx2.c, raster_avx512.c).
 *
 * Buffer layout. The screen is cut into 32x8-pixel tiles, each into 8 subtiles of 8x4 pixels:
 * subtile k covers columns 8*(k&3)..+7 and rows 4*(k>>2)..+3 of its tile. Per subtile the buffer
 * holds a 32-bit coverage mask m (bit 8*r + c = pixel column c, row r of the subtile) and two
 * depths, za (whole subtile) and zm (the pixels in m), with zm >= za whenever m != 0. The depth
 * of pixel p is B(p) = m(p) ? zm : za: every point farther than B(p) (d < B(p)) is hidden there.
 *
 * Bit-exactness. Every path computes the same values: coverage comes from exact integer and
 * double arithmetic (no rounding can differ), depths from the same float operations in the same
 * order, min/max written as (a < b ? a : b) like the SSE/AVX instructions, and every raster file
 * disables floating-point contraction so that no compiler can fuse a multiply and an add in one
 * path but not in another. */
#ifndef SL_RASTER_INTERNAL_H
#define SL_RASTER_INTERNAL_H

#include "core/sl_core.h"
#include "sightline/raster.h"

#include <stdatomic.h>

#define SL_RT_TILE_W 32 /* the SIMD kernels divide by it with >> 5 */
#define SL_RT_TILE_H 8
#define SL_RT_SUBTILES 8
#define SL_RT_SUB_W 8
#define SL_RT_SUB_H 4
#define SL_RT_SUBPIX 256       /* fixed-point units per pixel (8 sub-pixel bits) */
#define SL_RT_MAX_DIM 8192     /* largest width/height */
#define SL_RT_GUARD_PX 8000.0f /* guard band beyond each screen edge before clipping in x/y */
#define SL_RT_SNAP_LIMIT 16300.0f /* |pixel coordinate| bound after clipping: keeps |X| < 2^22 */
#define SL_RT_BIG (1 << 30)    /* "no bound" for column thresholds */

/* Fixed-count loops over lanes, corners and edges in the SIMD kernels are unrolled, so that their
 * vectors stay in registers (GCC does not peel them at -O2). */
#if defined(__clang__)
#define SL_RT_UNROLL _Pragma("clang loop unroll(full)")
#elif defined(__GNUC__)
#define SL_RT_UNROLL _Pragma("GCC unroll 8")
#else
#define SL_RT_UNROLL
#endif

/* Coverage rules for set-up triangles. OUTER is the query rule: every pixel whose square may meet
 * the unsnapped triangle. */
enum { SL_RT_CENTER = 0, SL_RT_INNER = 1, SL_RT_OUTER = 2 };

/* Depths of one tile: whole-subtile depth za and mask depth zm of its 8 subtiles (one cache line). */
typedef struct sl_rt_tile_depth {
    float za[SL_RT_SUBTILES];
    float zm[SL_RT_SUBTILES];
} sl_rt_tile_depth;

/* What the kernels write into or read. mask has 8 words per tile, tile-major, row-major tiles.
 * Lazy clear: row_empty[ty] != 0 says tile row ty is cleared (every subtile m = 0, za = zm = 0)
 * whatever its memory holds; the context writes the zeros into a row before an occluder reaches
 * it (raster.c, sl_rt_fill_rows). Readers take such a row as zero: the query kernels read
 * sl_rt_zero_tile in its place, the rectangle test goes through sl_rt_rect_occluded. */
typedef struct sl_rt_target {
    uint32_t *mask;
    sl_rt_tile_depth *depth;
    const uint8_t *row_empty; /* tiles_y flags */
    int32_t empty_rows;       /* how many are set */
    int32_t tiles_x, tiles_y;
    int32_t width, height; /* real pixels (queries stop there) */
} sl_rt_target;

/* A cleared tile (all-zero bits), what the query kernels read for a tile of an empty row. */
typedef struct sl_rt_zero_tile_t {
    _Alignas(64) sl_rt_tile_depth depth;
    _Alignas(32) uint32_t mask[SL_RT_SUBTILES];
} sl_rt_zero_tile_t;
extern const sl_rt_zero_tile_t sl_rt_zero_tile;

/* The mask words and depths of tile ti in tile row ty, as the lazy clear defines them. */
static inline const uint32_t *sl_rt_tile_mask(const sl_rt_target *t, int32_t ty, size_t ti)
{
    return t->row_empty[ty] ? sl_rt_zero_tile.mask : t->mask + ti * SL_RT_SUBTILES;
}
static inline const sl_rt_tile_depth *sl_rt_tile_depths(const sl_rt_target *t, int32_t ty, size_t ti)
{
    return t->row_empty[ty] ? &sl_rt_zero_tile.depth : &t->depth[ti];
}

/* A triangle set up for the kernels.
 * Coverage: for pixel row j, edge e gives the column threshold t_e(j) = ceil(num_e(j) / den_e) with
 * num_e(j) = num0[e] + j*nstep[e] (exact integers below 2^53 in doubles, so the correctly rounded
 * quotient has the exact ceiling; den > 0, at most 2^31), clamped to [col0, col1]. Edge 0 bounds from the left (first
 * covered column), edge 1 from the right (first uncovered column), edge 2 from the left when
 * cap == +SL_RT_BIG and from the right when cap == -SL_RT_BIG:
 *     xl = max(t0, min(t2, cap)),  xr = min(t1, max(t2, cap)),  row covered on [xl, xr)
 * for rows in [row0, row1). Horizontal edges only limit the rows; their slot holds a dummy edge.
 * Depth: for subtile k of the tile at pixel (x, y), the extreme depth over its sample area is
 *     z = ((z0 + zdx*(float)(x - x_ref)) + zdy*(float)(y - y_ref)) + off[k]
 * then max(z, zclamp) for occluders (farthest vertex) or min(z, zclamp) for queries (nearest). */
typedef struct sl_rt_tri {
    double num0[3], nstep[3], den[3];
    float off[SL_RT_SUBTILES];
    float z0, zdx, zdy, zclamp;
    int32_t x_ref, y_ref;
    int32_t col0, col1, row0, row1; /* pixel bounds, half-open, inside the padded screen */
    int32_t cap;
    /* Pixel rows [ja, jb] (inclusive) whose centres lie within edge e's vertical extent. On a row
     * outside it the other two edges alone give the exact span (the triangle is their wedge
     * there), so a kernel may skip the edge, using col0 (left) or col1 (right) instead. Set to
     * the full range where that does not hold (INNER/OUTER margins) and to an empty one for a
     * dummy edge. */
    int32_t ja[3], jb[3];
} sl_rt_tri;

/* ---- front end: transform, clip, snap, set up (raster_setup.c) ---- */

/* Per-frame projection parameters derived from the context. */
typedef struct sl_rt_view {
    float half_w, half_h;   /* viewport half size in pixels */
    float guard_x, guard_y; /* guard band as clip-space factors: |x| <= guard_x * w */
    float near_w;
    sl_raster_depth depth;
    int32_t pad_w, pad_h;   /* padded pixel size (tiles * tile size) */
    int32_t width, height;
} sl_rt_view;

/* Counters of the front end. */
typedef struct sl_rt_counters {
    uint64_t submitted, rejected_index, rejected_nonfinite, culled_outside, culled_backface, degenerate, clipped,
        rasterized, bin_refs;
} sl_rt_counters;

/* A snapped triangle ready for setup: oriented (positive area), front-facing, with its pixel
 * bounds; what the front end hands on and what bins store (64 bytes). */
typedef struct sl_rt_prim {
    int32_t X[3], Y[3]; /* 1/256 pixel */
    float d[3];
    int32_t col0, col1, row0, row1;
    double area;        /* twice the area, in (1/256 pixel)^2, > 0: an integer below 2^47, exact */
} sl_rt_prim;
/* the SIMD front ends write prims as two 32-byte rows of 32-bit fields in this order */
_Static_assert(sizeof(sl_rt_prim) == 64 && offsetof(sl_rt_prim, col0) == 36 && offsetof(sl_rt_prim, area) == 56,
               "sl_rt_prim layout");

/* Description of a triangle batch as the API receives it. */
typedef struct sl_rt_batch {
    const float *vertices;
    uint32_t vertex_count;
    const uint32_t *indices;
    uint32_t triangle_count;
    uint32_t stride;
    const float *m; /* model-to-clip, column-major */
    sl_raster_backface backface;
} sl_rt_batch;

/* Largest number of prepared triangles one input triangle can give (a clipped polygon's fan). */
#define SL_RT_FAN_MAX 10

/* The kernels of one instruction set. Tile ranges are half-open. */
typedef struct sl_rt_kernels {
    sl_raster_isa isa;
    /* Merge an occluder into tiles [tx0,tx1) x [ty0,ty1), already clipped to its pixel bounds. */
    void (*raster)(const sl_rt_target *t, const sl_rt_tri *tri, int32_t tx0, int32_t tx1, int32_t ty0, int32_t ty1);
    /* Query: true when some pixel the triangle covers may show it (whole triangle). */
    bool (*query_tri)(const sl_rt_target *t, const sl_rt_tri *tri);
    /* True when every pixel of [x0,x1) x [y0,y1) (inside the screen, non-empty) hides depth d. */
    bool (*rect_occluded)(const sl_rt_target *t, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d);
    /* Front end: triangles *next.. of a batch (up to last) into prepared occluders, in order, written to
     * out while a whole group still fits (cap >= 8 * SL_RT_FAN_MAX); advances *next past the triangles
     * consumed and returns the number of prims. Every path gives the same prims and counts as
     * sl_rt_front_prims. */
    uint32_t (*front)(const sl_rt_view *v, int mode, const sl_rt_batch *b, uint32_t *next, uint32_t last,
                      sl_rt_counters *cnt, sl_rt_prim *out, uint32_t cap);
    /* Set up and merge prims [0, n), in order, into the tiles [tx0,tx1) x [ty0,ty1) of the target
     * (a bin, or the whole screen). Same buffer as sl_rt_setup + raster for each prim. */
    void (*render)(const sl_rt_target *t, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0, int32_t tx1,
                   int32_t ty0, int32_t ty1);
} sl_rt_kernels;

extern const sl_rt_kernels sl_rt_kernels_scalar;
#if defined(__x86_64__) || defined(__i386__)
#define SL_RT_X86 1
extern const sl_rt_kernels sl_rt_kernels_sse41;
extern const sl_rt_kernels sl_rt_kernels_avx2;
extern const sl_rt_kernels sl_rt_kernels_avx512;
#endif

void sl_rt_view_init(sl_rt_view *v, uint32_t width, uint32_t height, float near_w, sl_raster_depth depth);
/* Clip-space position of vertex (x,y,z,1): ((m0*x + m4*y) + m8*z) + m12 per row, no contraction. */
void sl_rt_transform(const float *m, const float *p, float out[4]);
/* Snap a clip-space point with w >= near_w: fixed-point pixel position (1/256 px) and depth.
 * False when out of the snap range or non-finite. */
bool sl_rt_snap(const sl_rt_view *v, const float c[4], int32_t *X, int32_t *Y, float *d);
/* Depth of a clip-space point (w > 0) in the view's convention, computed as for vertices. */
float sl_rt_depth_of(const sl_rt_view *v, const float c[4]);
/* First half of the setup of a snapped triangle (query = the OUTER rule's bounds inside the
 * real screen): winding, orientation, pixel bounds. Returns 1 on success, 0 when culled as a
 * back face, -1 when degenerate, -2 when its bounds hold no pixel. */
int sl_rt_prepare(const sl_rt_view *v, const int32_t X[3], const int32_t Y[3], const float d[3], int mode,
                  bool query, sl_raster_backface backface, sl_rt_prim *out);
/* Second half, for `mode`, query = nearest-depth planes: edges and depth plane. False when a
 * horizontal edge leaves no pixel row. Deterministic: every path and bin gets the same bits. */
bool sl_rt_setup(const sl_rt_prim *p, int mode, bool query, sl_rt_tri *out);
/* The scalar front end (the reference of every kernel's `front`): transform, reject, clip, snap
 * and prepare triangles *next.. (up to last) into out while SL_RT_FAN_MAX more fit in cap; advances
 * *next and returns the number of prims written. */
uint32_t sl_rt_front_prims(const sl_rt_view *v, int mode, const sl_rt_batch *b, uint32_t *next, uint32_t last,
                           sl_rt_counters *cnt, sl_rt_prim *out, uint32_t cap);
/* sl_rt_setup, tile clipping and raster for each prim in turn: the reference of every `render`. */
void sl_rt_render_each(void (*raster)(const sl_rt_target *, const sl_rt_tri *, int32_t, int32_t, int32_t, int32_t),
                       const sl_rt_target *t, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0, int32_t tx1,
                       int32_t ty0, int32_t ty1);

/* Mesh query over a batch: returns the query answer. */
sl_raster_result sl_rt_query_batch(const sl_rt_view *v, const sl_rt_kernels *k, const sl_rt_target *t,
                                   const sl_rt_batch *b);

/* k->rect_occluded over the rows of [x0,x1) x [y0,y1) that hold data; a cleared row hides d only
 * when 0 > d. The answer is that of an eagerly cleared buffer (raster.c). */
bool sl_rt_rect_occluded(const sl_rt_kernels *k, const sl_rt_target *t, int32_t x0, int32_t y0, int32_t x1,
                         int32_t y1, float d);

/* ---- bins and thread pool (raster_bins.c) ---- */

typedef struct sl_rt_bins sl_rt_bins;
sl_status sl_rt_bins_create(const sl_allocator *alloc, int32_t tiles_x, int32_t tiles_y, uint32_t bins_x,
                            uint32_t bins_y, uint32_t slot_count, sl_rt_bins **out, sl_error *err);
void sl_rt_bins_destroy(sl_rt_bins *b);
uint32_t sl_rt_bins_count(const sl_rt_bins *b);
size_t sl_rt_bins_memory(const sl_rt_bins *b);
/* Forget every queued triangle and recycle the storage (exclusive use). */
void sl_rt_bins_reset(sl_rt_bins *b);
/* Front end of slot: store prim and queue it in every bin it overlaps; adds to *refs. False when
 * out of memory. */
bool sl_rt_bins_add(sl_rt_bins *b, uint32_t slot, const sl_rt_prim *prim, uint64_t *refs);
/* Set up (for mode) and rasterize what has been published to bin (all slots, in slot order);
 * returns the count. */
uint32_t sl_rt_bins_render(sl_rt_bins *b, const sl_rt_kernels *k, const sl_rt_target *t, int mode, uint32_t bin);

typedef struct sl_rt_pool sl_rt_pool;
typedef void (*sl_rt_job_fn)(void *arg, uint32_t worker);
/* Start `workers` threads (the caller is worker 0 of every job, they are 1..workers). */
sl_status sl_rt_pool_create(const sl_allocator *alloc, uint32_t workers, sl_rt_pool **out, sl_error *err);
void sl_rt_pool_destroy_n(sl_rt_pool *p, uint32_t workers);
/* Run fn(arg, i) on every worker and the caller (i = 0) and wait for all. */
void sl_rt_pool_run(sl_rt_pool *p, sl_rt_job_fn fn, void *arg);

/* ---- access for tests and benchmarks (raster.c) ---- */

/* The buffer and the projection of a context (read-only views). */
const sl_rt_target *sl_rt_target_of(const sl_raster *ctx);
const sl_rt_view *sl_rt_view_of(const sl_raster *ctx);
/* Write the zeros of every row the lazy clear left empty, so that the raw buffer is what an eager
 * clear would hold (tests compare raw buffers after it; exclusive use). */
void sl_rt_settle(sl_raster *ctx);
/* sl_raster_test_aabb corner by corner, for a finite, non-empty box: the reference of the SIMD
 * version (same answers, tested). */
sl_raster_result sl_rt_test_aabb_scalar(const sl_raster *ctx, const float box_min[3], const float box_max[3],
                                        const float world_to_clip[16]);

/* ---- scalar helpers shared by every path ---- */

static inline float sl_rt_minf(float a, float b) { return a < b ? a : b; } /* = minps(a, b) */
static inline float sl_rt_maxf(float a, float b) { return a > b ? a : b; } /* = maxps(a, b) */
static inline int32_t sl_rt_mini(int32_t a, int32_t b) { return a < b ? a : b; }
static inline int32_t sl_rt_maxi(int32_t a, int32_t b) { return a > b ? a : b; }

/* Bits [lo, 32) set; lo >= 32 gives 0 (like vpsllvd). lo must be >= 0. */
static inline uint32_t sl_rt_ones_from(int32_t lo) { return lo >= 32 ? 0u : ~0u << lo; }

/* Transpose 8 row masks (row r, byte c = columns 8c..8c+7) into 8 subtile masks. */
static inline void sl_rt_rows_to_subtiles(const uint32_t rows[8], uint32_t sub[8])
{
    for (int g = 0; g < 2; g++)
        for (int c = 0; c < 4; c++) {
            uint32_t s = 0;
            for (int r = 0; r < 4; r++)
                s |= ((rows[4 * g + r] >> (8 * c)) & 0xFFu) << (8 * r);
            sub[4 * g + c] = s;
        }
}

/* The merge of one occluder subtile (coverage c != 0 at depth z) into (m, za, zm); see
 * docs/rasterizer.md. Every SIMD path implements exactly this. When the old mask lies inside c
 * (no old pixel keeps zm), the new layer simply replaces it: every pixel of c is at least z. */
static inline void sl_rt_merge(uint32_t c, float z, uint32_t *m, float *za, float *zm)
{
    if (c == 0 || !(z > *za))
        return;
    bool repl = (*m & ~c) == 0 || (z > *zm && (z - *zm) > (*zm - *za));
    uint32_t nm = repl ? c : (*m | c);
    float nz = repl ? z : sl_rt_minf(*zm, z);
    if (nm == ~0u) {
        *za = nz;
        *m = 0;
    } else {
        *m = nm;
    }
    *zm = nz;
}

/* Query test of one subtile: true when every pixel of c hides depth z. */
static inline bool sl_rt_subtile_hides(uint32_t c, float z, uint32_t m, float za, float zm)
{
    return c == 0 || za > z || (zm > z && (c & ~m) == 0);
}

#endif

/* The oracle's reference rasterizer: exact, deterministic, scalar. One call draws one object's
 * triangles into an id + depth buffer.
 *
 * Conventions (docs/oracle.md):
 *  - clip space is OpenGL's (-w <= x, y, z <= w); triangles are clipped against the near and far
 *    planes and a guard band of +-SL_REFRAST_GUARD_PX pixels around the screen centre, never
 *    against the screen sides (bounding boxes are clamped to the screen instead);
 *  - screen x grows right, y grows down (row 0 is the top); pixel (x, y) has its centre at
 *    (x + 0.5, y + 0.5); vertices are snapped to 1/256 pixel (SL_REFRAST_SUBPIXEL_BITS);
 *  - a centre is covered when it lies strictly inside the snapped triangle, or exactly on a top or
 *    left edge (the top-left rule): edge functions are exact 64-bit integers;
 *  - depth is the reversed depth (1 - z/w)/2, affine in screen space: the plane through the
 *    exact (unsnapped) projected vertices, evaluated afresh at every pixel centre in double
 *    precision, clamped to the triangle's vertex range, stored as float;
 *  - a fragment replaces the stored one when it is nearer (greater depth), or equally near with a
 *    lower object id. The kept (depth, id) is therefore the maximum depth and the lowest id among
 *    the fragments at that depth: a pure function of the set of fragments, whatever the drawing
 *    order. Two buffers drawn from disjoint sets of objects merge with the same rule
 *    (sl_refrast_merge) into exactly the buffer one thread would have drawn.
 */
#ifndef SL_TRUTH_REFRAST_H
#define SL_TRUTH_REFRAST_H

#include "core/sl_core.h"

#define SL_REFRAST_SUBPIXEL_BITS 8
#define SL_REFRAST_SUBPIXEL (1 << SL_REFRAST_SUBPIXEL_BITS)
/* Vertices are kept within this many pixels of the screen centre (clipping against the band), so
 * snapped coordinates fit 30 bits and edge functions 62. */
#define SL_REFRAST_GUARD_PX (1 << 20)
/* Which facing to skip. Front faces are counter-clockwise in normalized device coordinates. */
typedef enum sl_refrast_cull { SL_REFRAST_CULL_NONE = 0, SL_REFRAST_CULL_BACK = 1, SL_REFRAST_CULL_FRONT = 2 } sl_refrast_cull;

/* A buffer to draw into. */
typedef struct sl_refrast_target {
    uint32_t width, height;
    uint32_t *ids;
    float *depth;
    uint32_t *overdraw;          /* NULL: not counted */
    double guard_x, guard_y;     /* guard band half-widths in NDC units */
} sl_refrast_target;

/* Per-thread scratch space for transformed vertices. */
typedef struct sl_refrast_scratch {
    double *clip;                /* 4 per vertex */
    struct svert *screen;        /* projected and snapped position and depth, valid when code == 0 */
    uint8_t *code;               /* outcode: bit set per clip plane the vertex is outside */
    size_t cap;
} sl_refrast_scratch;

/* Fill a target with "nothing": ids SL_NONE, depth 0, overdraw 0. */
void sl_refrast_clear(const sl_refrast_target *t);

/* Merge rows [y0, y1) of src into dst with the depth rule above (overdraw counts add up). */
void sl_refrast_merge(const sl_refrast_target *dst, const sl_refrast_target *src, uint32_t y0, uint32_t y1);

/* Can an object with this world box cover a pixel centre? From the world-to-clip matrix
 * (column-major doubles): false only when the box lies outside a frustum plane of the matrix (the
 * shared classifier, sl_frustum_classify_box, with its plane slack), or its projection (with
 * every corner in front of the eye) lies between pixel centres with a margin. */
bool sl_refrast_box_visible(const double vp[16], const sl_aabb *box, uint32_t width, uint32_t height);

/* Grow the scratch space to hold n vertices. */
bool sl_refrast_scratch_reserve(const sl_allocator *a, sl_refrast_scratch *s, size_t n);
void sl_refrast_scratch_free(const sl_allocator *a, sl_refrast_scratch *s);

/* Object-to-clip matrix: the view-projection vp (column-major) times the object's 3x4 affine t.
 * Shared by the oracle and the cullers that reproduce its fragments (cull/occlusion/object_tests.c, exact.c): the same
 * operations in the same order give bit-identical matrices. */
static inline void sl_refrast_compose(const double vp[16], const sl_affine *t, double m[16])
{
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double s = col == 3 ? vp[12 + row] : 0.0;
            for (int k = 0; k < 3; k++)
                s += vp[k * 4 + row] * (double)t->m[k * 4 + col];
            m[col * 4 + row] = s;
        }
}

/* Draw one object: positions (3 floats per vertex) transformed by the object-to-clip matrix m
 * (column-major doubles), triangles from indices (3 per triangle, each < vertex_count). */
void sl_refrast_mesh(const sl_refrast_target *t, sl_refrast_scratch *s, const double m[16], const float *positions,
                    uint32_t vertex_count, const uint32_t *indices, uint32_t triangle_count, uint32_t id,
                    sl_refrast_cull cull);

/* The same with the fragments counted (the CPU draw backend's occlusion queries, cull/backend_cpu.c):
 * returns the number of fragments at least as near as the depth stored where they fall (zf >=
 * depth, before the fragment's own write), every triangle's fragments counted (an overlap counts
 * twice, as GL_SAMPLES_PASSED does with one sample per pixel and glDepthFunc(GL_LEQUAL) in the
 * standard depth order). test_only: nothing is written (a query draw, depth writes off); else
 * fragments are stored by the rule above, exactly as sl_refrast_mesh stores them. */
uint64_t sl_refrast_mesh_count(const sl_refrast_target *t, sl_refrast_scratch *s, const double m[16],
                               const float *positions, uint32_t vertex_count, const uint32_t *indices,
                               uint32_t triangle_count, uint32_t id, sl_refrast_cull cull, bool test_only);

#endif

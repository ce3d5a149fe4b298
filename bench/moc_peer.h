/* A tiny C interface to Intel's Masked Occlusion Culling (MOC) for the side-by-side rasterizer
 * benchmark (bench_raster_throughput --peer moc). Built only when CMake is given -DSL_MOC_DIR=<MOC
 * checkout> (SL_HAVE_MOC is then defined); MOC's code is never part of this repository.
 *
 * Conventions are MOC's: vertices are read as (x, y, w) at byte offsets 0, offset_y, offset_w of each
 * stride-byte vertex; with a matrix (column-major, OpenGL, as Sightline's model_to_clip) the value at
 * offset_w is the model z and clip w = m[3] x + m[7] y + m[11] z + m[15]. Depth is 1/w. TestRect takes
 * NDC (x right, y up) and the rectangle's nearest clip w. */
#ifndef SL_BENCH_MOC_PEER_H
#define SL_BENCH_MOC_PEER_H

#ifdef __cplusplus
extern "C" {
#endif

typedef struct slmoc slmoc;

/* MOC's instruction sets (its Implementation enum). */
enum { SLMOC_SSE2 = 0, SLMOC_SSE41 = 1, SLMOC_AVX2 = 2, SLMOC_AVX512 = 3 };
/* MOC's answers. */
enum { SLMOC_VISIBLE = 0, SLMOC_OCCLUDED = 1, SLMOC_VIEW_CULLED = 3 };
/* backface: 0 none, 1 cull clockwise, 2 cull counter-clockwise (MOC's BackfaceWinding). */

/* Create a context asking for instruction set `isa` (MOC picks the lower of it and what the CPU
 * has: check slmoc_isa). NULL when out of memory. */
slmoc *slmoc_create(int isa);
void slmoc_destroy(slmoc *m);
/* The instruction set the context runs. */
int slmoc_isa(const slmoc *m);
const char *slmoc_isa_name(int isa);
/* Width a multiple of 8, height of 4; the buffer is undefined until slmoc_clear. */
void slmoc_set_resolution(slmoc *m, unsigned width, unsigned height);
void slmoc_set_near_clip(slmoc *m, float near_w);
void slmoc_clear(slmoc *m);
/* RenderTriangles, clipping against every plane (MOC's default) when clip is nonzero, against none
 * (CLIP_PLANE_NONE: the caller promises nothing needs clipping) when 0; returns VISIBLE or VIEW_CULLED. */
int slmoc_render(slmoc *m, const float *vertices, const unsigned *indices, int triangle_count,
                 const float model_to_clip[16], int backface, int stride, int offset_y, int offset_w, int clip);
int slmoc_test_rect(const slmoc *m, float xmin, float ymin, float xmax, float ymax, float wmin);
int slmoc_test_triangles(slmoc *m, const float *vertices, const unsigned *indices, int triangle_count,
                         const float model_to_clip[16], int backface, int stride, int offset_y, int offset_w);

#ifdef __cplusplus
}
#endif
#endif

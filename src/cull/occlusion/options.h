/* The options shared by the occlusion methods (sl_occ_common: rasterizer, occluder selection,
 * debugging, res=any|culling and inner=hull|faces; sl_occ_mesh_tests: the shared hidden-object
 * tests), their help lines and the readers. */
#ifndef SL_CULL_OCCLUSION_OPTIONS_H
#define SL_CULL_OCCLUSION_OPTIONS_H

#include "cull/culler_internal.h"

/* ---- options shared by the methods ---- */

typedef struct sl_occ_common {
    uint32_t threads;         /* rasterizer threads (the caller included) */
    uint32_t isa;             /* sl_raster_isa */
    uint32_t leaf_size;       /* BVH leaf size */
    float inset;
    bool all_objects;         /* every object may occlude (its own mesh), not only OCCLUDER ones */
    uint32_t occluders;       /* most occluders chosen per frame */
    uint32_t budget;          /* their triangle budget */
    float min_quality;        /* least Coorg-Teller quality of a chosen occluder */
    const char *dump;         /* PNG prefix for the depth buffer and pyramid of frame debug_frame */
    const char *record;       /* file recording frame debug_frame's occluders and queries */
    uint32_t debug_frame;
    char dump_buf[256], record_buf[256];
    bool res_culling;         /* res=culling: conservative at the culling resolution only (the
                                 pixel-centre tests may be used) */
    bool res_any;             /* res=any (the default of a method that reads SL_OCC_OPT_RES): occluders
                                 by inner coverage (every face eroded on screen by the pixel
                                 footprint), tests by outer coverage, no pixel-centre test; both
                                 false: a method without the option (its own rules) */
    bool inner_faces;         /* inner=faces: res=any's prisms eroded face by face (render_prism_eroded)
                                 instead of by their convex silhouettes (render_prism_hull) */
} sl_occ_common;

/* Default inset (metres) of a prism drawn by its eroded silhouette (res=any, inner=hull): the
 * silhouette rule keeps every covered pixel inside the prism's projection by itself, so the inset
 * only has to absorb the float rounding of the prism's vertices (add_prism raises it where the
 * coordinates need more); the 0.1 m of the other modes shrank every prism by 9 cm more than that
 * (docs/occlusion.md, "The thin inset of res=any"). */
#define SL_OCC_THIN_INSET 0.01f

/* SL_OCC_OPT_THIN_INSET: the method draws prisms through sl_occ_raster (sl_occ_render_prism_hull
 * under res=any, inner=hull, where sl_occ_usable does not need the inset on screen): its `inset`
 * defaults to SL_OCC_THIN_INSET there instead of 0.1 m. */
enum { SL_OCC_OPT_RASTER = 1, SL_OCC_OPT_SELECT = 2, SL_OCC_OPT_DEBUG = 4, SL_OCC_OPT_RES = 8, SL_OCC_OPT_THIN_INSET = 16 };

/* Read the shared options named by `which` (SL_OCC_OPT_*), with the method's defaults for
 * occluders and budget. SL_OCC_OPT_RES reads `res` and, with res=culling, sets *g (may be NULL)
 * to SL_CONSERVATIVE_AT_RESOLUTION. */
sl_status sl_occ_configure_common(sl_opts *o, uint32_t which, uint32_t def_occluders, uint32_t def_budget,
                                  sl_occ_common *c, sl_error *err);
/* With res=any (c->res_culling false), an option whose test samples pixel centres at the culling
 * resolution (`key`, value `value`) must be 0: fails naming it otherwise. */
sl_status sl_occ_require_res_culling(const sl_opts *o, const sl_occ_common *c, const char *key, uint32_t value,
                                     sl_error *err);
/* Guarantee of a method that read SL_OCC_OPT_RES (res=any: SL_CONSERVATIVE). */
static inline sl_cull_guarantee sl_occ_res_guarantee(const sl_occ_common *c)
{
    return c->res_culling ? SL_CONSERVATIVE_AT_RESOLUTION : SL_CONSERVATIVE;
}
/* Help lines of the shared options. */
#define SL_OCC_HELP_RASTER \
    "threads=1..16 (default 1): rasterizer threads, the caller included (used for batches of 512+ triangles)\n" \
    "isa=auto|scalar|sse41|avx2|avx512 (default auto): rasterizer instruction set\n"
#define SL_OCC_HELP_RES \
    "res=any|culling (default any): any: conservative at every render resolution and sample position " \
    "(occluders by inner coverage, tests by outer coverage, no pixel-centre tests); culling: conservative " \
    "at the culling resolution's pixel centres only (tighter: the centre-sampled tests below apply)\n" \
    "inner=hull|faces (default hull): with res=any, a building's prism is eroded by the pixel footprint " \
    "along the silhouette of each convex piece (hull) or along every face's edges (faces: looser, the " \
    "rule before)\n"
#define SL_OCC_HELP_DEBUG \
    "dump=PREFIX (default none): at frame debug_frame write PREFIX-depth.png and, where the method has one, " \
    "PREFIX-pyramid.png (its pyramid or grid)\n" \
    "record=FILE (default none): record frame debug_frame's occluders and queries for replay\n" \
    "debug_frame=N (default 0): the cull call (0 = first) that dump and record capture\n"

/* When an object whose box looks visible is tested by its own triangles (options mesh_test,
 * sample_tris, sample_px of the methods that offer them). */
typedef struct sl_occ_mesh_tests {
    uint32_t mesh_test;       /* outward-conservative test (sl_raster_test_triangles) up to this many
                                 triangles (0: never) */
    uint32_t sample_tris;     /* pixel-centre test (sl_occ_test_object_sampled) up to this many
                                 triangles (0: never) ... */
    uint32_t sample_px;       /* ... when its box's rectangle holds at most this many pixels */
} sl_occ_mesh_tests;

#define SL_OCC_HELP_MESH_TESTS \
    "mesh_test=0..100000 (default 64): test an object whose box looks visible by its own triangles, " \
    "rasterized outward-conservatively, when it has at most this many (0: never)\n" \
    "sample_tris=0..1000000 (default 0; 64 with res=culling, which it needs): test an object whose box looks " \
    "visible by its own triangles sampled at pixel centres (as the oracle) when it has at most this many and its " \
    "box covers at most sample_px pixels (0: never)\n" \
    "sample_px=0..1024 (default 256): largest box rectangle (pixels) of a pixel-centre test\n" \
    "shared=BOOL (default true): false turns both tests above off (mesh_test and sample_tris read as 0), leaving " \
    "the method's own test alone (a testing aid: the mutation check and tests/test_method_own.c use it)\n"

/* Read mesh_test, sample_tris, sample_px and shared (false: mesh_test = sample_tris = 0), after
 * sl_occ_configure_common read c's res: the pixel-centre test needs res=culling, and is off by
 * default otherwise. */
sl_status sl_occ_configure_mesh_tests(sl_opts *o, const sl_occ_common *c, sl_occ_mesh_tests *t, sl_error *err);

#endif

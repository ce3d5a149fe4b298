/* Shared machinery of the online occlusion methods (hzb, hom, lazygrid, lazygrid-z, busygrid,
 * frusta, plp, cplp): the per-frame view, box projection, the front-to-back BVH walk, occluder
 * proxies and their selection, the base every method builds on (BVH, proxies, selection buffers,
 * refit on scene change), screen pyramids, a rasterizer wrapper that counts, records and dumps,
 * objects tested by their own triangles, and the debugging recorder/replayer.
 *
 * Occluder proxies (docs/occlusion.md, "Occluders"). A proxy is geometry that lies INSIDE an
 * object's solid, so that whatever it hides the object hides too; the methods render proxies,
 * never anything larger than the original:
 *  - PRISM: a 2.5D footprint (sl_scene_footprint, inside its building by construction: roof at the
 *    eave, walls moved inward by the window recess) shrunk further by `inset` metres in every
 *    direction (polygon offset inward, roof lowered, base raised). The inset is what makes the
 *    proxy conservative against the oracle's pixel sampling: a pixel centre the rasterizer counts
 *    as covered by the shrunk prism is at least SL_OCC_MIN_INSET_PX pixels inside the building's
 *    silhouette whenever inset * focal / distance >= SL_OCC_MIN_INSET_PX, so the independent
 *    1/256-pixel snapping of rasterizer and oracle cannot disagree there. Beyond that distance a
 *    prism is not used (sl_occ_usable). A closed outward-wound solid: back faces may be culled.
 *  - MESH: the object's own triangles (objects flagged SL_OBJECT_OCCLUDER without a footprint,
 *    e.g. the solid world faces of a Quake III map), with the object's current transform, so a
 *    moving occluder is rendered where it is. Each triangle is shrunk on screen by
 *    SL_OCC_MIN_INSET_PX and drawn at its farthest depth, so that the independent snapping of
 *    rasterizer and oracle cannot disagree about a covered pixel centre (docs/occlusion.md).
 *    With res=any's silhouette rule (inner=hull) prisms and the convex parts of meshes are drawn
 *    by their eroded convex silhouettes instead (render_prism_hull, render_mesh_hull;
 *    docs/culler-contract.md, "Guarantees and resolution").
 *  - SCENE_MESH: a 3D occluder mesh of the scene (sl_scene_add_occluder), trusted to lie inside.
 * The meshoptimizer simplifier is not used: its output is not guaranteed to lie inside the
 * original, and a proxy must never exceed the original's silhouette.
 *
 * Everything here is allocation-free per frame except the rasterizer's (re)creation when the
 * camera's resolution changes and the debugging outputs of the frame asked for.
 */
#ifndef SL_CULL_OCCLUDERS_H
#define SL_CULL_OCCLUDERS_H

#include "culler_internal.h"

#include "accel/bvh_internal.h"
#include "scene/scene_internal.h"
#include "raster/raster_ref.h"
#include "convex_parts.h"

#include <math.h>
#include "sightline/accel.h"
#include "sightline/raster.h"

/* Pixels a prism proxy must lie inside its object's silhouette: 8 times the combined snapping
 * error of the rasterizer and the oracle (1/512 pixel each, plus float transform rounding). */
#define SL_OCC_MIN_INSET_PX SL_MARGIN_INSET_PX /* core/margins.h */

/* Branch-free float min/max without libm's NaN rules (compiles to minss/maxss; with a NaN they
 * return the second argument). */
static inline float sl_occ_minf(float a, float b) { return a < b ? a : b; }
static inline float sl_occ_maxf(float a, float b) { return a > b ? a : b; }

/* ---- the frame's view ---- */

typedef struct sl_occ_view {
    sl_camera cam;
    sl_mat4 vp;               /* world to clip (float, what the rasterizer is given) */
    sl_vec3 eye, fwd;
    sl_frustum fr;
    float slack[6];           /* plane slack (sl_margin_plane_slack) */
    bool ortho;
    float focal;              /* pixels per metre at unit forward distance (perspective), or pixels
                                 per metre (orthographic) */
    uint32_t width, height;
    sl_raster_depth depth;    /* INV_W for perspective, LINEAR_Z for orthographic */
    /* the near region (the points nearer than the near plane that a pixel's ray can pass): every
     * such point lies at forward depth below near_depth and (perspective) within near_reach of
     * the eye, both grown for rounding */
    float near_depth, near_reach;
} sl_occ_view;

/* Fill a view from a validated camera. */
void sl_occ_view_init(sl_occ_view *v, const sl_camera *cam);

/* A box's screen footprint: the half-open pixel rectangle of every pixel its projection touches
 * (grown by 1/64 pixel for rounding) and the depth of its nearest point in the rasterizer's
 * convention (larger = nearer), nudged nearer by 2^-20 relative. */
typedef struct sl_occ_rect {
    int32_t x0, y0, x1, y1;
    float dnear;
} sl_occ_rect;

enum {
    SL_OCC_OUT = 0,    /* beyond a frustum plane (or off screen): invisible */
    SL_OCC_RECT = 1,   /* rect and dnear are valid */
    SL_OCC_NEAR = 2    /* crosses the near plane, contains the eye or is not finite: treat as visible,
                          rect is the whole screen and dnear +infinity */
};

/* Project box b. Returns SL_OCC_OUT, SL_OCC_RECT or SL_OCC_NEAR. */
int sl_occ_project_box(const sl_occ_view *v, const sl_aabb *b, sl_occ_rect *r);

/* Forward (eye-space) depth range of a box: min and max of dot(fwd, p - eye) over its corners. */
static inline void sl_occ_box_zrange(const sl_occ_view *v, const sl_aabb *b, float *zmin, float *zmax)
{
    const float f[3] = {v->fwd.x, v->fwd.y, v->fwd.z};
    const float lo[3] = {b->min.x - v->eye.x, b->min.y - v->eye.y, b->min.z - v->eye.z};
    const float hi[3] = {b->max.x - v->eye.x, b->max.y - v->eye.y, b->max.z - v->eye.z};
    float a = 0, c = 0;
    for (int i = 0; i < 3; i++) {
        float p = f[i] * lo[i], q = f[i] * hi[i];
        a += p < q ? p : q;
        c += p < q ? q : p;
    }
    *zmin = a;
    *zmax = c;
}

/* Does box b keep out of the view's near region (no point of it nearer than the near plane on a
 * pixel's ray)? Conservative: may say no for a box that does. */
bool sl_occ_near_clear(const sl_occ_view *v, const sl_aabb *b);

/* Frustum classification with plane masks (as vfc): -1 outside, else the mask of the planes the
 * box straddles (0: wholly inside). */
int sl_occ_frustum_classify(const sl_occ_view *v, const sl_aabb *b, uint32_t mask);

/* True when point p lies in box b grown by g. */
static inline bool sl_occ_point_in_box(sl_vec3 p, const sl_aabb *b, float g)
{
    return p.x >= b->min.x - g && p.x <= b->max.x + g && p.y >= b->min.y - g && p.y <= b->max.y + g &&
           p.z >= b->min.z - g && p.z <= b->max.z + g;
}

/* ---- the front-to-back BVH walk every method uses ---- */

/* What a walk asks its method. Boxes beyond a frustum plane are skipped before any question. */
typedef struct sl_occ_walk {
    /* Skip this box: a node's subtree (slot: its node slot) or an object of a leaf that holds more
     * than one (slot SL_NONE; a one-object leaf's box is the node's)? NULL: never. */
    bool (*skip)(void *ctx, uint32_t slot, const sl_aabb *box);
    /* Every object reached, in the walk's front-to-back order; NULL: append it to out. */
    void (*visit)(void *ctx, uint32_t object, const sl_aabb *box);
    void *ctx;
    uint32_t *out;            /* with visit NULL: the objects reached (count of them) */
    uint32_t count;
} sl_occ_walk;

/* Walk the BVH nearer child first (sl_bvh_right_first) with the view's frustum plane masks.
 * Returns the nodes visited; *objects_tested (may be NULL) counts the leaf objects looked at. */
uint64_t sl_occ_walk_bvh(const struct sl_bvh_t *bvh, const sl_occ_view *v, sl_occ_walk *w,
                         uint64_t *objects_tested);

/* ---- occluder proxies ---- */

typedef enum sl_occ_kind { SL_OCC_PRISM = 1, SL_OCC_MESH = 2, SL_OCC_SCENE_MESH = 3 } sl_occ_kind;

typedef struct sl_occ_proxy {
    uint32_t object;          /* the object it stands for, or SL_NONE */
    uint32_t kind;            /* sl_occ_kind */
    uint32_t mesh;            /* MESH, SCENE_MESH: the scene mesh */
    uint32_t source;          /* PRISM: footprint index; SCENE_MESH: occluder index */
    uint32_t first, count;    /* PRISM: triangles [first, first+count) of prism_idx (3 indices each) */
    uint32_t face_first, face_count; /* planar convex faces for shadow frusta (faces[]) */
    uint32_t triangles;       /* triangles rendered for it */
    float inset;              /* metres inside the object (0: coincides, MESH) */
    float area;               /* half the surface area: the mean projected area of a convex solid */
    sl_aabb box;              /* world box (PRISM, SCENE_MESH; MESH reads the object's current box) */
    bool closed;              /* closed, outward-wound: back faces may be culled */
    bool enabled;             /* PRISM: false once its object moved away from the footprint */
} sl_occ_proxy;

/* A planar convex polygon of a proxy (a prism wall, a convex piece of a roof, a mesh triangle),
 * vertices counter-clockwise seen from the side its normal points to. */
typedef struct sl_occ_face {
    uint32_t proxy;
    uint32_t first, count;    /* vertices in face_verts, world coordinates; count 0 when the set was
                                 made without `faces` (then only the plane, centre and area are kept)
                                 (MESH proxies: static objects only, a moving one's are not kept) */
    sl_vec3 normal;           /* unit */
    sl_vec3 centre;
    float area;
} sl_occ_face;

typedef struct sl_occ_options {
    float inset;              /* metres a prism is shrunk by (0.01 .. 10) */
    bool all_objects;         /* every object without a prism gets a MESH proxy, not only OCCLUDER ones */
    bool faces;               /* keep the convex faces' vertices (frusta, hom) and MESH faces */
    uint32_t mesh_faces;      /* largest triangles kept per MESH proxy as faces */
    bool screen_margin;       /* every prism is drawn eroded on screen by SL_OCC_MIN_INSET_PX beyond
                                 the pixel footprint (render_prism_hull, res=any): its inset need not
                                 be SL_OCC_MIN_INSET_PX on screen, sl_occ_usable skips that test */
} sl_occ_options;

typedef struct sl_occ_set {
    sl_allocator alloc;
    sl_scene scene;
    sl_occ_options opt;
    uint32_t proxy_count;
    sl_occ_proxy *proxies;
    uint32_t object_count;
    uint32_t *object_proxy;   /* per object: its proxy or SL_NONE */
    sl_affine *prism_xf;      /* per proxy: the object's transform when the prism was made */
    float *prism_pos;         /* world vertices of every prism, 3 floats each */
    uint32_t prism_vertex_count;
    uint32_t *prism_idx;      /* 3 per triangle, into prism_pos */
    uint32_t prism_tri_count;
    sl_occ_face *faces;
    uint32_t face_count;
    sl_vec3 *face_verts;
    uint32_t face_vert_count;
    uint32_t prisms, prisms_rejected, meshes, scene_meshes;
    sl_occ_cparts *cparts;    /* screen_margin: per scene mesh, the convex parts of those that MESH and
                                 SCENE_MESH proxies draw (built false for the others) */
    uint32_t cparts_count;    /* the scene's mesh count */
} sl_occ_set;

/* Build the proxies of a scene. */
sl_status sl_occ_set_create(sl_scene scene, const sl_occ_options *opt, const sl_allocator *alloc, sl_occ_set **out,
                            sl_error *err);
void sl_occ_set_destroy(sl_occ_set *s);
/* Objects moved: a prism whose object's transform changed is disabled (the footprint no longer
 * describes it); MESH proxies follow their object by themselves. */
void sl_occ_set_scene_changed(sl_occ_set *s);

/* Current world box of a proxy. */
static inline sl_aabb sl_occ_proxy_box(const sl_occ_set *s, const sl_occ_proxy *p)
{
    return p->kind == SL_OCC_MESH ? sl_scene_object_bounds_array(s->scene)[p->object] : p->box;
}

/* May the proxy be rendered this frame? Enabled; the eye outside its (and its object's) box; a
 * proxy that lies inside a solid (PRISM, SCENE_MESH, the MESH of a closed convex object) only
 * when both boxes keep out of the near region (sl_occ_near_clear); a prism near enough that its
 * inset is at least SL_OCC_MIN_INSET_PX pixels on screen. */
bool sl_occ_usable(const sl_occ_set *s, uint32_t proxy, const sl_occ_view *v);

/* Coorg-Teller occluder quality, summed over the proxy's faces: -A (N.V) / |D|^2 with V the unit
 * direction from the eye to the face centre and D the vector to it (a solid-angle estimate); for a
 * MESH proxy, its half area over the squared distance to its box centre. */
float sl_occ_quality(const sl_occ_set *s, uint32_t proxy, const sl_occ_view *v);

/* Per BVH node slot, the largest proxy area in its subtree (0 where none), for pruning the
 * selection walk: area / dist^2(eye, node) bounds every quality below the node. */
void sl_occ_node_areas(const sl_occ_set *s, const struct sl_bvh_t *bvh, float *node_area);

typedef struct sl_occ_pick {
    uint32_t proxy;
    float quality;
} sl_occ_pick;

/* Choose this frame's occluders: the usable proxies in the frustum whose quality is at least
 * min_quality, the best max_count of them, then in decreasing quality while their triangles fit
 * in tri_budget. heap must hold max_count entries. Writes the choice to out sorted nearest first
 * (the order to render them in; out[i].quality then holds the squared distance to the proxy's
 * box) and returns its length. nodes_visited (may be NULL) counts the walk. */
uint32_t sl_occ_select(const sl_occ_set *s, const sl_occ_view *v, const struct sl_bvh_t *bvh, const float *node_area,
                       uint32_t max_count, uint32_t tri_budget, float min_quality, sl_occ_pick *heap,
                       sl_occ_pick *out, uint64_t *nodes_visited);

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

enum { SL_OCC_OPT_RASTER = 1, SL_OCC_OPT_SELECT = 2, SL_OCC_OPT_DEBUG = 4, SL_OCC_OPT_RES = 8 };

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

/* ---- the base of every method: BVH, proxies, selection buffers ---- */

/* What every occlusion method holds besides its own buffers: the object BVH, the occluder proxies,
 * the selection's per-node areas and pick buffers (methods that select only), and the scratch of
 * sl_cull_sort_ids. */
typedef struct sl_occ_base {
    sl_allocator alloc;
    sl_scene scene;
    const char *method;       /* static name, for error messages */
    sl_bvh bvh;
    bool bvh_owned;           /* false: the shared handle's tree (sl_cull_extras.accel), not refitted here */
    sl_occ_set *occ;
    float *node_area;         /* per BVH node slot (sl_occ_node_areas); NULL unless selecting */
    uint32_t node_slots;
    sl_occ_pick *heap, *picks;/* pick_cap entries each */
    uint32_t *pick_ids;       /* the frame's chosen proxies, nearest first */
    uint32_t pick_cap;        /* 0 unless selecting */
    uint32_t object_count;
    uint32_t *sort_scratch;   /* object_count entries */
} sl_occ_base;

/* Build the BVH (c->leaf_size; the shared handle's when extras has one, sl_cull_object_bvh) and
 * the proxies (c->inset, c->all_objects, faces/mesh_faces as given); when `select`, also the node
 * areas and the buffers for c->occluders picks. extras may be NULL. On failure everything built is
 * freed and the error is prefixed with `method`. */
sl_status sl_occ_base_init(sl_occ_base *b, sl_scene scene, const char *method, const sl_occ_common *c, bool faces,
                           uint32_t mesh_faces, bool select, const sl_cull_extras *extras, const sl_allocator *alloc,
                           sl_error *err);
void sl_occ_base_free(sl_occ_base *b);
/* Objects moved: refit the BVH (rebuilt when the refit degrades it; a shared tree is left to its
 * owner, accel.h), refresh the node areas and disable the prisms of moved objects. */
sl_status sl_occ_base_scene_changed(sl_occ_base *b, sl_error *err);
/* Choose the frame's occluders (sl_occ_select with c's count, budget and min_quality) into
 * b->picks and b->pick_ids, nearest first; returns their number. */
uint32_t sl_occ_base_select(sl_occ_base *b, const sl_occ_view *v, const sl_occ_common *c, uint64_t *nodes_visited);

/* ---- the rasterizer wrapper ---- */

/* A vertex projected in double precision (MESH occluders, pixel-centre tests). */
typedef struct sl_occ_screen_vertex {
    double x, y;              /* screen position (pixels) */
    float d;                  /* depth in the rasterizer's convention (larger = nearer) */
    bool ok;                  /* in front of the eye (w > 1e-5) and finite */
    bool between;             /* and between the near and far planes */
} sl_occ_screen_vertex;

typedef struct sl_occ_recorder sl_occ_recorder;

typedef struct sl_occ_raster {
    sl_allocator alloc;
    sl_raster *ctx;
    uint32_t width, height;
    uint32_t threads, isa;
    bool erode;               /* res=any: occluders by inner coverage (render_prism_hull or _eroded,
                                 MESH and SCENE_MESH proxies shrunk by the pixel footprint) */
    bool hull;                /* res=any, inner=hull: prisms by their convex silhouettes */
    uint32_t *batch;          /* prism indices of one batch */
    size_t batch_cap;         /* in indices */
    float *shrunk;            /* one MESH proxy's triangles shrunk on screen, 3 vertices x 3 floats each */
    uint32_t *shrunk_idx;     /* 0, 1, 2, ... */
    size_t shrunk_cap;        /* in triangles: the largest MESH proxy */
    struct sl_occ_screen_vertex *shrunk_proj; /* its vertices projected */
    size_t shrunk_proj_cap;   /* in vertices */
    uint32_t *stamp;          /* per proxy: frame + 1 when rendered this frame */
    uint32_t proxy_count;
    uint32_t frame_id;        /* increments per frame (never 0 in stamp) */
    uint64_t frame;           /* cull calls so far */
    /* counters of the frame */
    uint64_t queries, pixel_queries, occluders_rendered, triangles_rendered;
    /* debugging */
    const char *dump, *record;
    uint32_t debug_frame;
    sl_occ_recorder *rec;     /* non-NULL while frame debug_frame is being recorded */
    char dump_path[256], record_path[256];
} sl_occ_raster;

sl_status sl_occ_raster_init(sl_occ_raster *r, const sl_occ_common *c, const sl_occ_set *set,
                             const sl_allocator *alloc, sl_error *err);
void sl_occ_raster_free(sl_occ_raster *r);
/* Start a frame: (re)create the context at the camera's resolution when it changed, clear it in
 * the view's depth mode, start recording if this is the debug frame. */
sl_status sl_occ_raster_begin(sl_occ_raster *r, const sl_occ_view *v, sl_error *err);
/* Render proxies (skipping those already rendered this frame): prisms in one batch (threaded when
 * large), meshes one call each. Returns the number rendered. */
uint32_t sl_occ_raster_render(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const uint32_t *proxies,
                              uint32_t n);
/* Was the proxy rendered this frame? */
static inline bool sl_occ_raster_rendered(const sl_occ_raster *r, uint32_t proxy)
{
    return r->stamp[proxy] == r->frame_id;
}
/* test_rect through the wrapper: counted (queries, pixels) and recorded. */
sl_raster_result sl_occ_raster_test(sl_occ_raster *r, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d);
/* Test an object by its own triangles (sl_raster_test_triangles, two-sided, with its current
 * transform): counted as one query and recorded. */
sl_raster_result sl_occ_raster_test_object(sl_occ_raster *r, sl_scene scene, const sl_occ_view *v, uint32_t object);
/* Most pixels of an object's box rectangle for sl_occ_test_object_sampled. */
#define SL_OCC_SAMPLED_MAX_PX 1024
/* Test an object by its own triangles sampled at pixel centres, the way the oracle decides
 * visibility: every pixel centre within SL_OCC_MIN_INSET_PX of one of its triangles (two-sided,
 * current transform) is tested at that triangle's nearest depth, and a centre hidden in any of
 * the layers (rasterizers that hold valid occluders only) or in the exact layer (may be NULL) is
 * hidden. OCCLUDED when every such
 * centre is hidden, including when there is none (the object covers no pixel centre at the
 * camera's resolution: the oracle, and a renderer without multisampling, draw nothing of it);
 * VISIBLE otherwise, and whenever rect (the object's box, SL_OCC_RECT) holds more than
 * SL_OCC_SAMPLED_MAX_PX pixels or a vertex is not in front of the eye. Counted as one query of
 * layers[0] plus the pixel queries. */
struct sl_occ_exact;
sl_raster_result sl_occ_test_object_sampled(sl_occ_raster *const *layers, uint32_t layer_count,
                                            struct sl_occ_exact *exact, sl_scene scene, const sl_occ_view *v,
                                            uint32_t object, const sl_occ_rect *rect);
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

/* ---- the exact layer: visible objects drawn with the oracle's own rasterizer ----
 * Far, small objects (a pixel or two at the end of a street) hide each other, but as occluders
 * they are too thin for the conservative rasterizer (MESH proxies drop triangles thinner than
 * SL_OCC_MIN_INSET_PX). Drawn with the point oracle's reference rasterizer (truth/raster_ref.h),
 * with the same world-to-clip matrix, object transform and facing rule, an object's fragments
 * (covered pixel centres and their depths) are bit-identical to the ones the oracle draws for it
 * at the same resolution. Where such a fragment is nearer than every point a tested object may
 * show at that pixel centre, with a margin far above float rounding, the oracle gives the pixel
 * to something else. Only visible objects' true triangles are drawn (no proxies), so the layer
 * holds nothing that is not there. Pixels never drawn hold depth 0 (hides nothing). */
typedef struct sl_occ_exact {
    sl_allocator alloc;
    uint32_t width, height;   /* allocated size */
    float *depth;             /* oracle's reversed depth, 0 where nothing was drawn */
    uint32_t *ids;
    sl_refrast_scratch scratch;
    sl_occ_rect *dirty;       /* rectangles drawn this frame: cleared at the next begin */
    size_t dirty_count, dirty_cap;
    uint32_t drawn;           /* objects drawn this frame */
    double vp[16];            /* the oracle's world-to-clip matrix */
    uint64_t pixel_tests;
} sl_occ_exact;

sl_status sl_occ_exact_init(sl_occ_exact *e, const sl_allocator *alloc, sl_error *err);
void sl_occ_exact_free(sl_occ_exact *e);
/* Start a frame: size the buffers for the view, clear what the last frame drew. */
sl_status sl_occ_exact_begin(sl_occ_exact *e, const sl_occ_view *v, sl_error *err);
/* Draw an object (its own triangles, the oracle's facing rule) whose box covers rectangle r. */
sl_status sl_occ_exact_draw(sl_occ_exact *e, sl_scene scene, uint32_t object, const sl_occ_rect *r, sl_error *err);
/* Does the layer prove pixel (x, y) hidden for surfaces whose oracle depth there is at most rd
 * (reversed depth (1 - z/w) / 2, larger = nearer, as computed from the oracle's matrix)? The
 * oracle's own order is compared: converting to 1/w is not exact, because z and w come from a
 * float matrix whose rows are not exactly proportional. The margin (2^-20 relative) covers the
 * float storage of both depths and the ties the oracle breaks by object id. */
static inline bool sl_occ_exact_hides(sl_occ_exact *e, int32_t x, int32_t y, double rd)
{
    if (!e || !e->drawn)
        return false;
    e->pixel_tests++;
    double stored = (double)e->depth[(size_t)y * e->width + (size_t)x];
    return stored > 0.0 && stored > rd + fabs(rd) * SL_MARGIN_REL;
}
/* The largest oracle depth of a point in the box, grown by 2^-20 of its coordinates (a corner's:
 * the reversed depth is monotone along segments in front of the eye); +infinity when a corner is
 * not in front of the eye. */
double sl_occ_exact_box_depth(const sl_occ_exact *e, const sl_aabb *b);
/* A box whose rectangle r (sl_occ_project_box) looks visible, tested at the pixel centres its
 * silhouette covers, at depth r->dnear: true when each such centre is hidden in some layer. The
 * box is grown by 2^-20 of its coordinates (object boxes are computed in float, the oracle places
 * vertices in double), its corners projected in double, and centres within 1/64 pixel of the
 * silhouette count as covered (the oracle snaps vertices by at most 1/512 pixel). First one query
 * for the rectangle of the centres inside the corners' bounding box (the border rows and columns
 * the box only grazes are left out; no centre at all: hidden); then, when r is at most max_rows
 * rows tall, the centres inside the convex hull of the corners, row by row (the rows within one
 * 4-row band of subtiles as one rectangle, hidden in one layer; failing that, pixel by pixel in
 * the layers and the exact layer, which may be NULL, when the band holds at most 64 centres).
 * Everything in the box covers only centres its silhouette covers, at depths no nearer than its
 * nearest corner, so it is hidden from the oracle at the same resolution too. False when a corner
 * is not in front of the eye. */
bool sl_occ_box_rows_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact,
                            const sl_occ_view *v, const sl_aabb *box, const sl_occ_rect *r, uint32_t max_rows);
/* Is an object whose box looks visible hidden by its own triangles? Hidden when either test, as
 * configured by t, hides it: the pixel-centre test (sl_occ_test_object_sampled) over all the
 * layers, tried first (cheaper, and it answers most of the small objects it applies to), then the
 * outward-conservative mesh query in each layer. Queries leave the buffers unchanged, so the
 * order changes the cost, never the answer. False when the eye is in its box. *tests (may be
 * NULL) counts the objects tested. */
bool sl_occ_object_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact, sl_scene scene,
                          const sl_occ_view *v, uint32_t object, const sl_aabb *box, const sl_occ_mesh_tests *t,
                          uint64_t *tests);
/* End a frame: on the debug frame, write the recording and the dumps (the pyramid given as
 * `levels` float images, level i of size w_i x h_i, may be NULL). Debug output failures are
 * reported as errors of the cull call. */
typedef struct sl_occ_levels {
    uint32_t count;
    const float *const *data;
    const uint32_t *w, *h;
    bool opacity;             /* values are opacities in [0,1] (else depths, larger = nearer) */
} sl_occ_levels;
sl_status sl_occ_raster_end(sl_occ_raster *r, const sl_occ_levels *levels, sl_error *err);

/* ---- screen pyramids (hzb's max-depth pyramid, hom's opacity pyramid) ---- */

#define SL_OCC_MAX_LEVELS 24

/* Levels over the rasterizer's 8x4 subtiles: level 0 has one entry per subtile of the tiled
 * buffer, each next level half as many per axis (rounded up), down to 1x1. */
typedef struct sl_occ_pyramid {
    float *data;
    size_t cap;               /* entries allocated */
    uint32_t levels;
    uint32_t lw[SL_OCC_MAX_LEVELS], lh[SL_OCC_MAX_LEVELS];
    size_t loff[SL_OCC_MAX_LEVELS];
    const float *level_ptr[SL_OCC_MAX_LEVELS];
    uint32_t w, h;            /* screen size it was laid out for (0: none) */
} sl_occ_pyramid;

/* Lay the pyramid out for the rasterizer of a w x h screen; allocates only when the size changed
 * (*resized then true; may be NULL). */
sl_status sl_occ_pyramid_size(sl_occ_pyramid *p, const sl_allocator *alloc, const sl_raster *ctx, uint32_t w,
                              uint32_t h, bool *resized, sl_error *err);
void sl_occ_pyramid_free(sl_occ_pyramid *p, const sl_allocator *alloc);
/* Level 0 from the buffer: the farthest depth of each subtile (sl_raster_read_subtile_depth). */
void sl_occ_pyramid_read_base(sl_occ_pyramid *p, const sl_raster *ctx);
/* The pyramid as debugging levels. */
static inline sl_occ_levels sl_occ_pyramid_levels(const sl_occ_pyramid *p, bool opacity)
{
    sl_occ_levels l = {p->levels, p->level_ptr, p->lw, p->lh, opacity};
    return l;
}

/* ---- debugging (occlusion_debug.c) ---- */

/* Write a depth buffer (width x height floats, larger = nearer, 0 = empty) as a grey PNG: empty
 * pixels black, the rest from dark (far) to white (near) on a logarithmic ramp. */
sl_status sl_occ_write_depth_png(const char *path, const float *depth, uint32_t width, uint32_t height,
                                 const sl_allocator *alloc, sl_error *err);
/* Write pyramid levels in one grey PNG, mipmap style: level 0 on the left, the coarser levels
 * stacked top to bottom to its right, each at its own size (depths on the ramp of
 * sl_occ_write_depth_png, opacities from black 0 to white 1). */
sl_status sl_occ_write_levels_png(const char *path, const sl_occ_levels *levels, const sl_allocator *alloc,
                                  sl_error *err);

/* A recording of one frame: the rasterizer's options, every occluder batch (triangles expanded
 * to 3 vertices each, the model-to-clip matrix, the back-face mode) and every rectangle query with
 * its answer, in order. The file format is in docs/occlusion.md. */
sl_status sl_occ_recorder_create(const sl_allocator *alloc, const sl_raster_options *ropt, sl_raster_depth depth,
                                 sl_occ_recorder **out, sl_error *err);
void sl_occ_recorder_destroy(sl_occ_recorder *rec);
/* Append a batch (vertices at byte stride, indices) or a query; failures are sticky. */
void sl_occ_recorder_batch(sl_occ_recorder *rec, const float *vertices, uint32_t vertex_stride_bytes,
                           const uint32_t *indices, uint32_t triangle_count, const float m[16],
                           sl_raster_backface backface);
void sl_occ_recorder_query(sl_occ_recorder *rec, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d,
                           sl_raster_result result);
/* A triangle-mesh query (sl_raster_test_triangles) with its answer. */
void sl_occ_recorder_mesh_query(sl_occ_recorder *rec, const float *vertices, uint32_t vertex_stride_bytes,
                                const uint32_t *indices, uint32_t triangle_count, const float m[16],
                                sl_raster_backface backface, sl_raster_result result);
/* Write the recording atomically. */
sl_status sl_occ_recorder_save(sl_occ_recorder *rec, const char *path, sl_error *err);

/* sl_occ_replay_report and sl_occ_replay: sightline/cull.h. */
/* The same on a recording held in memory (`path` names it in messages; the fuzz target). */
sl_status sl_occ_replay_memory(const void *data, size_t size, const char *path, sl_raster_isa isa,
                               const sl_allocator *alloc, sl_occ_replay_report *out, sl_error *err);

#endif

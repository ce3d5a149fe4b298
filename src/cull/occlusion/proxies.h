/* Occluder proxies (docs/occlusion.md, "Occluders"). A proxy is geometry that lies INSIDE an
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
 *    by their eroded convex silhouettes instead (sl_occ_render_prism_hull, sl_occ_render_mesh_hull in inner_coverage.c;
 *    docs/culler-contract.md, "Guarantees and resolution").
 *  - SCENE_MESH: a 3D occluder mesh of the scene (sl_scene_add_occluder), trusted to lie inside.
 * The meshoptimizer simplifier is not used: its output is not guaranteed to lie inside the
 * original, and a proxy must never exceed the original's silhouette.
 * Here: the proxy set of a scene (sl_occ_set: built once, refreshed when objects move) and whether a
 * proxy may be rendered for a view (sl_occ_usable). The prisms' polygon geometry is core/polygon.h. */
#ifndef SL_CULL_OCCLUSION_PROXIES_H
#define SL_CULL_OCCLUSION_PROXIES_H

#include "cull/convex_parts.h"
#include "cull/occlusion/view.h"
#include "scene/scene_internal.h"

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
/* The `applicable` hook of the occlusion methods (sl_cull_method_applicable): config is a method
 * config whose first member is its sl_occ_common. False, with why, when the scene offers no
 * occluder: no footprint, no occluder mesh, no non-see-through SL_OBJECT_OCCLUDER object, and
 * all_objects is off. */
bool sl_occ_applicable(sl_scene scene, const void *config, char *why, size_t why_size);
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

#endif

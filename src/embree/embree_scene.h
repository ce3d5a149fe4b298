/* A scene as one Embree 3 triangle geometry, for ray casting: the samplers of the region layer
 * (guided visibility sampling), error renders, and any method that needs "first triangle along a
 * ray" (the region oracle may reuse it).
 *
 * Every triangle of every object, with the object's transform applied, goes into one world-space
 * vertex and index buffer (instances are flattened). Triangles are numbered globally in object
 * order: object o owns ids [first(o), first(o+1)), in its mesh's order, so a triangle id gives its
 * object in O(1) and an object's triangles are a range. A mirroring transform (negative
 * determinant) has its triangles' winding flipped, so that a world triangle is counter-clockwise
 * seen from its mesh-space front side.
 *
 * Hits follow the point oracle's rules (truth.h): both sides of a triangle are hit, except the back
 * faces of SL_OBJECT_CLOSED_CONVEX objects (skipped by an Embree intersection filter that exists
 * only when the scene has such objects). The scene is built with RTC_SCENE_FLAG_ROBUST, so rays do
 * not slip through the shared edges of a closed mesh.
 *
 * Each sl_es owns its RTCDevice (no global state). The scene is a snapshot: later changes to the
 * sl_scene (moved objects) are not seen. Tracing is safe from any number of threads at once; build
 * and destroy are not. */
#ifndef SL_REGION_EMBREE_SCENE_H
#define SL_REGION_EMBREE_SCENE_H

#include "sightline/camera.h"
#include "sightline/view.h"
#include "sightline/scene.h"

typedef struct sl_es sl_es;

/* Largest number of triangles (ids must fit below SL_NONE). */
#define SL_ES_MAX_TRIANGLES 0xfffffff0u

typedef struct sl_es_options {
    uint32_t threads;           /* Embree build threads; 0: all the machine offers. The hit results
                                   do not depend on it (see docs/gvs.md, "Determinism"). */
    uint32_t quality;           /* 0: medium (default), 1: low (fast build), 2: high (SAH splits) */
    bool draw_closed_backfaces; /* true: hit back faces of closed convex objects too */
} sl_es_options;

/* A ray: org + t*dir for t in [tnear, tfar]. dir need not be unit length; t is in units of dir. */
typedef struct sl_es_ray {
    float org[3];
    float tnear;
    float dir[3];
    float tfar;
} sl_es_ray;

/* The first hit: a global triangle id and its object, or SL_NONE for both on a miss. Triangles of
 * SL_OBJECT_SEE_THROUGH objects never stop a ray (docs/oracle.md): the nearest one in front of the
 * first solid hit (or anywhere along a missing ray) is reported apart. */
typedef struct sl_es_hit {
    uint32_t triangle;
    uint32_t object;
    float t;                    /* ray parameter of the hit (INFINITY on a miss) */
    uint32_t see_through_triangle; /* nearest see-through triangle before the hit, or SL_NONE */
    uint32_t see_through_object;   /* its object, or SL_NONE */
    float see_through_t;        /* its ray parameter (INFINITY when none) */
} sl_es_hit;

typedef struct sl_es_stats {
    uint32_t object_count;
    uint32_t triangle_count;
    uint32_t vertex_count;
    bool backface_filter;       /* a closed convex object exists and its back faces are skipped */
    double build_seconds;
    size_t memory_bytes;        /* our buffers (Embree's BVH is not counted) */
} sl_es_stats;

/* Build the Embree scene of all objects. opt and alloc may be NULL (defaults). Fails with
 * SL_ERROR_LIMIT past SL_ES_MAX_TRIANGLES triangles or 2^32-1 vertices, SL_ERROR_INTERNAL when
 * Embree reports an error (its message is included). An empty scene is allowed (every ray misses). */
sl_status sl_es_create(sl_scene scene, const sl_es_options *opt, const sl_allocator *alloc, sl_es **out, sl_error *err);
/* Release it. NULL is ignored. */
void sl_es_destroy(sl_es *es);

void sl_es_get_stats(const sl_es *es, sl_es_stats *out);
uint32_t sl_es_triangle_count(const sl_es *es);
uint32_t sl_es_object_count(const sl_es *es);
/* The object owning a triangle (triangle < count). */
uint32_t sl_es_triangle_object(const sl_es *es, uint32_t triangle);
/* First global triangle id of an object (object <= count: first(count) is the triangle count). */
uint32_t sl_es_object_first_triangle(const sl_es *es, uint32_t object);
/* World-space vertices of a triangle, counter-clockwise seen from its front. */
void sl_es_triangle_vertices(const sl_es *es, uint32_t triangle, double v[3][3]);
/* Bounds of all triangles (empty for an empty scene). */
sl_aabb sl_es_bounds(const sl_es *es);

/* Trace n rays (any n; batched internally through rtcIntersect1M) and write their first hits. */
void sl_es_trace(const sl_es *es, const sl_es_ray *rays, sl_es_hit *hits, uint32_t n);

/* Cast one ray per pixel centre of a camera (perspective or orthographic; near and far planes
 * bound the depth along the view direction, as for the point oracle) and write the global triangle
 * id seen by every pixel (SL_NONE for none) to tri_ids, width*height entries, row 0 at the top. */
sl_status sl_es_render_ids(const sl_es *es, const sl_camera *cam, uint32_t *tri_ids, sl_error *err);
/* The same for a view (view.h; any projection it takes, off-axis and infinite far included): one ray
 * per pixel centre of its normal-form image (sl_view_pixel_ray), the image the oracle renders. */
sl_status sl_es_render_view_ids(const sl_es *es, const sl_view *view, uint32_t *tri_ids, sl_error *err);

#endif

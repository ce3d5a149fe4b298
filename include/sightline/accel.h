/* Sightline acceleration structures: a bounding volume hierarchy over objects and a 2D scene grid.
 *
 * sl_bvh: a binary BVH over object world boxes, built with a binned surface area heuristic (SAH).
 *   It serves every culler: a front-to-back traversal with a per-node "descend?" callback (frustum
 *   and occlusion tests prune there) and a per-object callback, box and ray queries, a refit after
 *   dynamic objects moved, and a rebuild when refits have degraded the tree.
 * sl_grid: a uniform 2D grid over the XY plane; per cell the objects whose box overlaps it, their
 *   maximum height and a lower bound of the terrain; a 2D DDA walk along segments (horizon
 *   methods) and in-place updates for moved objects (cars).
 *
 * Thread safety: every const query (traversal, queries, stats, cell lookups, segment walks) may run
 * from any number of threads at once on one handle; they allocate nothing and keep their state on
 * the caller's stack. Refit, rebuild and update need exclusive access (no query in flight).
 * See docs/accel.md for the layout and the guarantees.
 */
#ifndef SIGHTLINE_ACCEL_H
#define SIGHTLINE_ACCEL_H

#include "core.h"
#include "geom.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ===== BVH ===================================================================================== */

typedef struct sl_bvh_t *sl_bvh;

/* Build options; a zero-initialised struct (or NULL) gives the defaults. */
typedef struct sl_bvh_options {
    uint32_t max_leaf_size;     /* most objects per leaf, 1..16; 0: 4 */
    uint32_t bin_count;         /* SAH bins on the longest centroid axis, 2..64; 0: 16 */
    uint32_t threads;           /* build threads; 0: the online CPUs (at most 16); 1: the caller only.
                                   The tree is identical whatever the thread count. */
    const sl_allocator *alloc;  /* NULL: the scene's allocator (sl_bvh_build) or the default one */
} sl_bvh_options;

/* Summary of a tree. SAH cost: sum over internal nodes of area(node)/area(root) plus sum over leaves
 * of area(leaf)/area(root) * objects(leaf) (node and object tests cost the same in a culler); when
 * the root has zero area every ratio counts as 1. */
typedef struct sl_bvh_stats {
    uint32_t object_count;
    uint32_t node_count;        /* internal nodes + leaves */
    uint32_t leaf_count;
    uint32_t depth;             /* levels: 0 for an empty tree, 1 for a single leaf */
    uint32_t max_leaf_size, bin_count;
    double sah_cost;            /* of the current boxes (after the last build or refit) */
    double build_sah_cost;      /* at the last build */
    double build_seconds;       /* wall time of the last build */
    size_t memory_bytes;
} sl_bvh_stats;

/* Build over the world boxes of every object of a scene. Fails, naming the object, on a box that
 * is not finite, inverted (min > max) or beyond +-1e30. An empty scene gives an empty tree. */
SL_API sl_status sl_bvh_build(sl_scene scene, const sl_bvh_options *options, sl_bvh *out, sl_error *err);
/* Build over a raw array of boxes; object ids are the array indices. */
SL_API sl_status sl_bvh_build_boxes(const sl_aabb *boxes, uint32_t count, const sl_bvh_options *options,
                                    sl_bvh *out, sl_error *err);
/* Release a tree. NULL is ignored. */
SL_API void sl_bvh_destroy(sl_bvh bvh);

/* Statistics of the tree. */
SL_API void sl_bvh_get_stats(sl_bvh bvh, sl_bvh_stats *out);
/* Number of objects the tree was built over. */
SL_API uint32_t sl_bvh_object_count(sl_bvh bvh);
/* Bounds of all objects (the root box); empty for an empty tree. */
SL_API sl_aabb sl_bvh_bounds(sl_bvh bvh);

/* Refit after objects moved (sl_scene_set_object_transform): re-reads every object's world box from
 * the scene and recomputes node boxes bottom-up in O(objects + nodes); the topology is kept. The
 * scene must have the object count the tree was built with (else rebuild). Needs exclusive access.
 * On failure the tree is unchanged. */
SL_API sl_status sl_bvh_refit(sl_bvh bvh, sl_scene scene, sl_error *err);
/* Refit from a raw array of boxes (count must equal the built object count). */
SL_API sl_status sl_bvh_refit_boxes(sl_bvh bvh, const sl_aabb *boxes, uint32_t count, sl_error *err);
/* Rebuild from the scene (same options) when the SAH cost of the current boxes exceeds max_ratio
 * times the cost at the last build (max_ratio <= 0 means 1.5), or when the scene's object count
 * changed. Call after sl_bvh_refit: the ratio uses the cost computed by the last refit. *rebuilt
 * (may be NULL) tells whether it rebuilt. On failure the old tree is kept. */
SL_API sl_status sl_bvh_rebuild_if_degraded(sl_bvh bvh, sl_scene scene, double max_ratio, bool *rebuilt,
                                            sl_error *err);

/* Traversal callbacks. `node` is a node index (see src/accel/bvh_internal.h for the layout).
 * sl_bvh_node_fn: return true to descend into the node (for a leaf: to report its objects), false
 * to skip its whole subtree. NULL means "always descend".
 * sl_bvh_object_fn: called once per object of a leaf entered; return false to stop the whole
 * traversal at once. */
typedef bool (*sl_bvh_node_fn)(void *user, uint32_t node, const sl_aabb *bounds);
typedef bool (*sl_bvh_object_fn)(void *user, uint32_t object, const sl_aabb *bounds);

/* Front-to-back depth-first traversal from eye. Ordering guarantee: at every internal node the
 * child whose box is nearer to eye (Euclidean distance from eye to the box, 0 inside; ties broken
 * by the distance to the box centre, then left first) is visited first, and its whole subtree is
 * finished before the other child is entered. Hence if object A is reported before object B, and
 * C_A, C_B are the children of their lowest common ancestor holding A and B, then
 * dist(eye, C_A) <= dist(eye, C_B) <= dist(eye, box of B). Node callbacks run in visiting order, so
 * an occlusion test sees every object reported before it. Returns the number of objects reported.
 * Allocation-free and safe to run concurrently. */
SL_API uint32_t sl_bvh_traverse(sl_bvh bvh, sl_vec3 eye, sl_bvh_node_fn node_fn, sl_bvh_object_fn object_fn,
                                void *user);

/* Objects whose box overlaps `box` (closed intervals: touching counts), in leaf order. Writes at
 * most `capacity` ids to out (may be NULL when capacity is 0) and returns the total number. */
SL_API uint32_t sl_bvh_query_aabb(sl_bvh bvh, const sl_aabb *box, uint32_t *out, uint32_t capacity);
/* Objects whose box the segment origin + t*dir, t in [0, tmax], touches (dir need not be unit;
 * tmax may be INFINITY), nearer child boxes first. Same output convention as sl_bvh_query_aabb. */
SL_API uint32_t sl_bvh_query_ray(sl_bvh bvh, sl_vec3 origin, sl_vec3 dir, float tmax, uint32_t *out,
                                 uint32_t capacity);

/* ===== shared per-scene acceleration ============================================================
 * sl_scene_accel holds a scene's object BVH once, for every culler created with it (cull.h,
 * sl_culler_create_with): a server with one culler per client keeps one tree, not one per client.
 * The methods that walk an object BVH (vfc and the occlusion framework's hzb, hom, frusta, lazygrid,
 * lazygrid_z, busygrid, and gl-stopwait, chc, chc++) use the handle's tree instead of building their own; their
 * leaf_size option must equal the handle's (else creation fails naming both); the other methods keep
 * no object BVH and ignore the handle.
 *
 * Objects moving (sl_scene_set_object_transform) with a shared handle: the owner calls
 * sl_scene_accel_scene_changed (refit, rebuild when degraded) while no culler that uses the handle
 * culls, then sl_culler_scene_changed on each of those cullers before its next cull (a culler with a
 * shared handle refits only what it owns, never the handle's tree).
 *
 * Thread safety: create, scene_changed and destroy need exclusive access (no culler using the handle
 * culling); the getters and every culler's reads of the tree may run on any number of threads at
 * once. The handle must outlive the cullers created with it; the scene must outlive the handle. */

typedef struct sl_scene_accel_t *sl_scene_accel;

typedef struct sl_scene_accel_options {
    uint32_t leaf_size;         /* most objects per BVH leaf, 1..16; 0: 4 (the methods' default) */
    uint32_t threads;           /* build threads, as sl_bvh_options.threads (the tree is the same) */
    const sl_allocator *alloc;  /* NULL: the default allocator */
} sl_scene_accel_options;

/* Build the handle's BVH over the scene's objects (what the methods would build: the SAH builder
 * with the default bins and leaf_size). options may be NULL. */
SL_API sl_status sl_scene_accel_create(sl_scene scene, const sl_scene_accel_options *options, sl_scene_accel *out,
                                       sl_error *err);
/* Release it (after every culler created with it). NULL is ignored. */
SL_API void sl_scene_accel_destroy(sl_scene_accel accel);
/* The scene, the object BVH and its leaf size. */
SL_API sl_scene sl_scene_accel_scene(sl_scene_accel accel);
SL_API sl_bvh sl_scene_accel_bvh(sl_scene_accel accel);
SL_API uint32_t sl_scene_accel_leaf_size(sl_scene_accel accel);
/* Objects moved: refit the tree and rebuild it when degraded (sl_bvh_rebuild_if_degraded with the
 * default ratio); exclusive access (see above). */
SL_API sl_status sl_scene_accel_scene_changed(sl_scene_accel accel, sl_error *err);
/* Bytes held by the handle (the tree included). */
SL_API size_t sl_scene_accel_memory(sl_scene_accel accel);

/* ===== 2D scene grid ============================================================================ */

typedef struct sl_grid_t *sl_grid;

/* Grid options; zero-initialised (or NULL) gives the defaults. */
typedef struct sl_grid_options {
    float cell_size;            /* edge of a square cell in metres, > 0; 0: automatic (about four
                                   objects per cell on average) */
    const sl_aabb *extent;      /* XY area to cover (z ignored); NULL: the objects' bounds */
    const sl_allocator *alloc;  /* NULL: the scene's allocator (sl_grid_build) or the default one */
} sl_grid_options;

typedef struct sl_grid_info {
    uint32_t nx, ny;            /* cells along x and y */
    float cell_size;
    float min_x, min_y;         /* corner of cell (0,0); cell (i,j) covers
                                   [min_x + i*cell, min_x + (i+1)*cell) x [min_y + j*cell, ...) */
    float max_x, max_y;         /* min + n*cell: the far edges (belonging to the last cells) */
    uint32_t object_count;
    uint64_t entry_count;       /* sum over cells of the objects listed */
    size_t memory_bytes;
} sl_grid_info;

/* Build a grid over a scene's objects. Per cell: the ids of the objects whose world box overlaps
 * the cell (ascending), the maximum z of those boxes (-INFINITY for an empty cell) and a lower
 * bound of the terrain over the cell (0 without terrain). Objects outside the extent are clipped. */
SL_API sl_status sl_grid_build(sl_scene scene, const sl_grid_options *options, sl_grid *out, sl_error *err);
/* Build over a raw array of boxes (ids are array indices; ground lower bound 0). */
SL_API sl_status sl_grid_build_boxes(const sl_aabb *boxes, uint32_t count, const sl_grid_options *options,
                                     sl_grid *out, sl_error *err);
/* Release a grid. NULL is ignored. */
SL_API void sl_grid_destroy(sl_grid grid);

/* Dimensions and counters. */
SL_API void sl_grid_get_info(sl_grid grid, sl_grid_info *out);
/* Cell containing world point (x, y). Returns false when the point is outside the grid (or not
 * finite); the cell is then the nearest one (clamped), or (0,0) for a non-finite point. */
SL_API bool sl_grid_cell_at(sl_grid grid, float x, float y, uint32_t *cx, uint32_t *cy);
/* Objects listed in a cell (ascending ids); *ids stays valid until the next update. Returns the
 * count (0 and *ids = NULL for a cell out of range). */
SL_API uint32_t sl_grid_cell_objects(sl_grid grid, uint32_t cx, uint32_t cy, const uint32_t **ids);
/* Maximum z of the boxes listed in a cell; -INFINITY when empty or out of range. */
SL_API float sl_grid_cell_max_height(sl_grid grid, uint32_t cx, uint32_t cy);
/* Lower bound of the ground height over a cell; 0 without terrain or out of range. */
SL_API float sl_grid_cell_ground_min(sl_grid grid, uint32_t cx, uint32_t cy);

/* Segment walk callback: cell (cx, cy) is crossed for segment parameters [t_enter, t_exit] of
 * a + t*(b-a). Return false to stop the walk. */
typedef bool (*sl_grid_cell_fn)(void *user, uint32_t cx, uint32_t cy, float t_enter, float t_exit);
/* Visit, in order from a to b, every cell the segment touches (a conservative 2D DDA): precisely
 * every cell whose rectangle grown by delta = 8*FLT_EPSILON*(largest |coordinate| of the grid +
 * cell size) meets the segment, so any point of the segment rounded to float lies in a visited cell
 * (sl_grid_cell_at), even on cell lines and corners. Order: by column along the major axis of the
 * segment, then by row in the segment's direction, which is the order of the segment's points; no
 * cell twice; consecutive cells are 8-neighbours; t_enter is nondecreasing. Returns the number of
 * cells visited; 0 for a segment farther than delta from the grid, or not finite. */
SL_API uint32_t sl_grid_walk_segment(sl_grid grid, sl_vec2 a, sl_vec2 b, sl_grid_cell_fn fn, void *user);

/* Move objects: re-read their world boxes from the scene and move their ids between cells (cell
 * lists stay ascending; max heights updated). Needs exclusive access. Fails, with the grid unchanged,
 * on an id out of range, a repeated id or a bad box. */
SL_API sl_status sl_grid_update_objects(sl_grid grid, sl_scene scene, const uint32_t *objects, uint32_t count,
                                        sl_error *err);
/* Same with explicit new boxes (boxes[i] is the new box of objects[i]). */
SL_API sl_status sl_grid_update_boxes(sl_grid grid, const uint32_t *objects, const sl_aabb *boxes, uint32_t count,
                                      sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

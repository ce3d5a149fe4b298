/* Internal layout of sl_bvh, for cullers that walk the nodes directly (no callback per node).
 *
 * Nodes are 32 bytes: the box, then `first` and `count`.
 *   leaf     (count >= 1): its objects are objects[first .. first+count), boxes in object_bounds[]
 *                          at the same slots (leaf order: every subtree covers a contiguous range).
 *   internal (count == 0): children are nodes[first] and nodes[first+1]; first is even, so a pair
 *                          shares one 64-byte cache line (the node array is 64-byte aligned).
 * The root is node 0. When the root is internal, slot 1 is padding (an empty box, never referenced)
 * so that pairs start at even slots. A parent's index is always below its children's, so a reverse
 * sweep over the slots visits children before parents (refit relies on this).
 * Depth (levels, root = 1) never exceeds SL_BVH_MAX_DEPTH: the builder switches to median splits
 * near the limit, so a depth-first walk needs at most SL_BVH_MAX_DEPTH - 1 stack entries.
 */
#ifndef SL_ACCEL_BVH_INTERNAL_H
#define SL_ACCEL_BVH_INTERNAL_H

#include "sightline/accel.h"
#include "core/sl_core.h"

#define SL_BVH_MAX_DEPTH 64
#define SL_BVH_MAX_LEAF_SIZE 16
#define SL_BVH_MAX_BINS 64
#define SL_BVH_DEFAULT_LEAF_SIZE 4
#define SL_BVH_DEFAULT_BINS 16
/* Coordinates beyond this are rejected: keeps every sum and area finite. */
#define SL_BVH_MAX_COORD 1e30f

typedef struct sl_bvh_node {
    sl_aabb box;
    uint32_t first;             /* leaf: first object slot; internal: left child (right = first + 1) */
    uint32_t count;             /* leaf: objects (>= 1); internal: 0 */
} sl_bvh_node;

_Static_assert(sizeof(sl_bvh_node) == 32, "sl_bvh_node must stay 32 bytes");

struct sl_bvh_t {
    sl_allocator alloc;
    sl_bvh_node *nodes;         /* node_slots entries, 64-byte aligned */
    uint32_t node_slots;        /* array length: node_count plus the padding slot (if any) */
    uint32_t node_count;        /* real nodes */
    uint32_t leaf_count;
    uint32_t depth;
    uint32_t *objects;          /* object ids in leaf order, object_count entries */
    sl_aabb *object_bounds;     /* object_bounds[i] is the world box of objects[i] */
    uint32_t object_count;
    uint32_t max_leaf_size, bin_count, threads;
    double build_sah, sah;
    double build_seconds;
};

static inline bool sl_bvh_node_is_leaf(const sl_bvh_node *n) { return n->count != 0; }

/* Squared distance from point e to box b (0 when inside). */
static inline float sl_bvh_dist2(const sl_aabb *b, const float e[3])
{
    float dx = SL_MAX(SL_MAX(b->min.x - e[0], e[0] - b->max.x), 0.0f);
    float dy = SL_MAX(SL_MAX(b->min.y - e[1], e[1] - b->max.y), 0.0f);
    float dz = SL_MAX(SL_MAX(b->min.z - e[2], e[2] - b->max.z), 0.0f);
    return dx * dx + dy * dy + dz * dz;
}

/* Squared distance from e to the centre of b, times 4 (the tie-breaker of the ordering). */
static inline float sl_bvh_centre_dist2(const sl_aabb *b, const float e[3])
{
    float dx = b->min.x + b->max.x - 2 * e[0], dy = b->min.y + b->max.y - 2 * e[1], dz = b->min.z + b->max.z - 2 * e[2];
    return dx * dx + dy * dy + dz * dz;
}

/* True when the right child of internal node n must be visited before the left one: the front-to-
 * back rule of sl_bvh_traverse, shared by every culler that walks the nodes itself. */
static inline bool sl_bvh_right_first(const sl_bvh_node *nodes, const sl_bvh_node *n, const float e[3])
{
    const sl_aabb *l = &nodes[n->first].box, *r = &nodes[n->first + 1].box;
    float dl = sl_bvh_dist2(l, e), dr = sl_bvh_dist2(r, e);
    if (dr != dl)
        return dr < dl;
    return sl_bvh_centre_dist2(r, e) < sl_bvh_centre_dist2(l, e);
}

/* Closed-interval overlap of two boxes. */
static inline bool sl_bvh_overlap(const sl_aabb *a, const sl_aabb *b)
{
    return a->min.x <= b->max.x && b->min.x <= a->max.x && a->min.y <= b->max.y && b->min.y <= a->max.y &&
           a->min.z <= b->max.z && b->min.z <= a->max.z;
}

#endif

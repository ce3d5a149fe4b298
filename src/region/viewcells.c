/* View cells: the regions a PVS is baked for, and the run-time lookup of the cell holding the eye.
 *
 * P. Wonka, "Occlusion Culling for Real-Time Rendering of Urban Environments", PhD thesis, TU Wien
 * 2001, section 5.3: the free space of the city (the ground not covered by buildings) is
 * triangulated with a constrained Delaunay triangulation refined until no edge exceeds a maximum
 * length, and each triangle becomes a prism up to the maximum eye height. Any other subdivision
 * works as well; a regular grid, the clusters of a Quake III map and an adaptive subdivision of a
 * navigable box are offered beside it.
 *
 * Refinement: GEOS (3.10+) triangulates a polygon with holes constrained by its edges but adds no
 * interior points. The boundary is therefore first densified to the maximum edge length, and the
 * triangles are then split at the midpoint of their longest edge until every edge is short enough
 * (longest-edge bisection keeps the smallest angle above half the initial one). The result may
 * have T-junctions between neighbours; cells only need to tile the free space, not to conform.
 *
 * Lookup: a bounding-box tree over the cells, median split on the longest axis, four cells per
 * leaf. For disjoint cells a point meets O(1) boxes per level, so a lookup costs O(log n). */
#include "region_internal.h"

#include "geos_util.h"
#include "scene/scene_internal.h"
#include "sightline/accel.h"

#include <math.h>
#include <stdlib.h>

#define DEFAULT_STREET_EDGE 12.0f
#define DEFAULT_GRID_EDGE 8.0f
#define DEFAULT_ADAPTIVE_EDGE 16.0f
#define DEFAULT_ADAPTIVE_MIN 2.0f
#define DEFAULT_EYE_MIN 1.0f
#define DEFAULT_EYE_MAX 2.0f
#define DEFAULT_MAX_CELLS 4000000u

/* ============================================================================================
 * Records, validation, the container
 * ============================================================================================ */

static bool finite_f(float v) { return isfinite(v); }

static sl_aabb prism_bounds(const sl_viewcell *c)
{
    sl_aabb b;
    b.min.x = fminf(c->tri[0].x, fminf(c->tri[1].x, c->tri[2].x));
    b.min.y = fminf(c->tri[0].y, fminf(c->tri[1].y, c->tri[2].y));
    b.max.x = fmaxf(c->tri[0].x, fmaxf(c->tri[1].x, c->tri[2].x));
    b.max.y = fmaxf(c->tri[0].y, fmaxf(c->tri[1].y, c->tri[2].y));
    b.min.z = c->z_min;
    b.max.z = c->z_max;
    return b;
}

static bool box_equal(const sl_aabb *a, const sl_aabb *b) { return memcmp(a, b, sizeof *a) == 0; }

sl_status sl_viewcell_validate(const sl_viewcell *c, uint32_t index, sl_error *err)
{
    const float *f = &c->tri[0].x;
    for (int i = 0; i < 6; i++)
        if (!finite_f(f[i]))
            return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: triangle coordinate %d is not finite", index, i);
    if (!finite_f(c->z_min) || !finite_f(c->z_max) || !sl_finite3(&c->bounds.min.x) || !sl_finite3(&c->bounds.max.x))
        return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: a height or bound is not finite", index);
    if (!(c->z_min <= c->z_max))
        return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: z_min %g is above z_max %g", index, (double)c->z_min,
                       (double)c->z_max);
    if (!(c->bounds.min.x <= c->bounds.max.x && c->bounds.min.y <= c->bounds.max.y &&
          c->bounds.min.z <= c->bounds.max.z))
        return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: inverted bounds", index);
    switch (c->shape) {
    case SL_CELL_PRISM: {
        double o = sl_orient2d(c->tri[0].x, c->tri[0].y, c->tri[1].x, c->tri[1].y, c->tri[2].x, c->tri[2].y);
        if (!(o > 0))
            return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: the prism's triangle is %s", index,
                           o < 0 ? "clockwise" : "degenerate");
        if (c->cluster != -1)
            return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: a prism with cluster %d (must be -1)", index,
                           c->cluster);
        sl_aabb b = prism_bounds(c);
        if (!box_equal(&b, &c->bounds))
            return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: bounds do not match the prism", index);
        return SL_OK;
    }
    case SL_CELL_BOX:
    case SL_CELL_CLUSTER:
        for (int i = 0; i < 6; i++)
            if (f[i] != 0)
                return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: a %s cell with a non-zero triangle", index,
                               c->shape == SL_CELL_BOX ? "box" : "cluster");
        if (c->shape == SL_CELL_BOX) {
            if (c->cluster != -1)
                return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: a box with cluster %d (must be -1)", index,
                               c->cluster);
        } else if (c->cluster < 0 || c->cluster >= SL_VC_MAX_CLUSTER) {
            return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: cluster %d is outside 0..%d", index, c->cluster,
                           SL_VC_MAX_CLUSTER - 1);
        }
        if (c->z_min != c->bounds.min.z || c->z_max != c->bounds.max.z)
            return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: z range does not match the bounds", index);
        return SL_OK;
    default:
        return sl_fail(err, SL_ERROR_FORMAT, "view cell %u: unknown shape %u", index, c->shape);
    }
}

static void destroy_cells(struct sl_viewcells_t *v)
{
    const sl_allocator *a = &v->alloc;
    sl_free(a, v->cells, (size_t)v->count * sizeof(sl_viewcell));
    sl_free(a, v->nodes, (size_t)v->node_count * sizeof(sl_vc_node));
    sl_free(a, v->order, (size_t)(v->count ? v->count : 1) * sizeof(uint32_t));
    sl_free(a, v->cluster_map, (size_t)v->cluster_span * sizeof(uint32_t));
    sl_free(a, v, sizeof *v);
}

void sl_viewcells_destroy(sl_viewcells v)
{
    if (v)
        destroy_cells(v);
}

/* Sorting cell indices by box centre along one axis (ties: by index, so the tree is a function of
 * the cells alone). */
typedef struct sort_key {
    float c;
    uint32_t id;
} sort_key;

static int cmp_key(const void *a, const void *b)
{
    const sort_key *x = a, *y = b;
    if (x->c != y->c)
        return x->c < y->c ? -1 : 1;
    return (x->id > y->id) - (x->id < y->id);
}

static float centre(const sl_aabb *b, int axis)
{
    const float *lo = &b->min.x, *hi = &b->max.x;
    return 0.5f * (lo[axis] + hi[axis]);
}

/* Build the subtree over order[first..first+n) at node index `at`; returns the next free node. */
static uint32_t build_node(struct sl_viewcells_t *v, sort_key *keys, uint32_t at, uint32_t first, uint32_t n,
                           uint32_t depth)
{
    sl_vc_node *node = &v->nodes[at];
    node->box = sl_aabb_empty();
    sl_aabb cb = sl_aabb_empty();
    for (uint32_t i = 0; i < n; i++) {
        const sl_aabb *b = &v->cells[v->order[first + i]].bounds;
        sl_aabb_merge(&node->box, b);
        sl_vec3 c = {centre(b, 0), centre(b, 1), centre(b, 2)};
        sl_aabb_grow(&cb, c);
    }
    if (n <= SL_VC_LEAF_SIZE || depth + 1 >= SL_VC_MAX_DEPTH) {
        node->first = first;
        node->count = n;
        return at + 1;
    }
    float ext[3] = {cb.max.x - cb.min.x, cb.max.y - cb.min.y, cb.max.z - cb.min.z};
    int axis = ext[1] > ext[0] ? 1 : 0;
    if (ext[2] > ext[axis])
        axis = 2;
    for (uint32_t i = 0; i < n; i++) {
        keys[i].id = v->order[first + i];
        keys[i].c = centre(&v->cells[keys[i].id].bounds, axis);
    }
    qsort(keys, n, sizeof *keys, cmp_key);
    for (uint32_t i = 0; i < n; i++)
        v->order[first + i] = keys[i].id;
    uint32_t half = n / 2;
    node->count = 0;
    uint32_t next = build_node(v, keys, at + 1, first, half, depth + 1);
    v->nodes[at].first = next; /* the right child; the left one is at + 1 */
    return build_node(v, keys, next, first + half, n - half, depth + 1);
}

/* Take ownership of `cells` (count records allocated with a, validated) and build the lookup. */
static sl_status make_cells(const sl_allocator *a, sl_viewcell *cells, uint32_t count, sl_viewcells *out,
                            sl_error *err)
{
    struct sl_viewcells_t *v = sl_calloc(a, 1, sizeof *v);
    if (!v) {
        sl_free(a, cells, (size_t)count * sizeof *cells);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "view cells: out of memory");
    }
    v->alloc = *a;
    v->cells = cells;
    v->count = count;
    int32_t max_cluster = -1;
    for (uint32_t i = 0; i < count; i++)
        if (cells[i].shape == SL_CELL_CLUSTER)
            max_cluster = SL_MAX(max_cluster, cells[i].cluster);
    /* at most 2n/leaf + 1 nodes for a median split; 2n + 1 is a safe bound for any n */
    size_t node_cap = 2 * (size_t)count + 1;
    v->nodes = sl_alloc(a, node_cap * sizeof(sl_vc_node));
    v->order = sl_alloc(a, (count ? count : 1) * sizeof(uint32_t));
    sort_key *keys = sl_alloc(a, (count ? count : 1) * sizeof(sort_key));
    if (max_cluster >= 0) {
        v->cluster_span = (uint32_t)max_cluster + 1;
        v->cluster_map = sl_alloc(a, v->cluster_span * sizeof(uint32_t));
    }
    if (!v->nodes || !v->order || !keys || (max_cluster >= 0 && !v->cluster_map)) {
        sl_free(a, keys, (count ? count : 1) * sizeof(sort_key));
        v->node_count = (uint32_t)node_cap;
        destroy_cells(v);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "view cells: out of memory for the lookup of %u cells", count);
    }
    v->node_count = (uint32_t)node_cap;
    if (v->cluster_map) {
        for (uint32_t i = 0; i < v->cluster_span; i++)
            v->cluster_map[i] = SL_NONE;
        for (uint32_t i = 0; i < count; i++) {
            if (cells[i].shape != SL_CELL_CLUSTER)
                continue;
            uint32_t c = (uint32_t)cells[i].cluster;
            if (v->cluster_map[c] != SL_NONE) {
                sl_status st = sl_fail(err, SL_ERROR_FORMAT, "view cell %u: cluster %u is already cell %u", i, c,
                                       v->cluster_map[c]);
                sl_free(a, keys, (count ? count : 1) * sizeof(sort_key));
                destroy_cells(v);
                return st;
            }
            v->cluster_map[c] = i;
        }
    }
    for (uint32_t i = 0; i < count; i++)
        v->order[i] = i;
    uint32_t used = count ? build_node(v, keys, 0, 0, count, 0) : 0;
    (void)used;
    sl_free(a, keys, (count ? count : 1) * sizeof(sort_key));
    v->key = sl_hash64(cells, (size_t)count * sizeof *cells, 0x5643454c4c53ull /* "VCELLS" */);
    *out = v;
    return SL_OK;
}

sl_status sl_viewcells_create(const sl_viewcell *cells, uint32_t count, const sl_allocator *alloc, sl_viewcells *out,
                              sl_error *err)
{
    if (!out || (count && !cells))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_create: cells and out must not be NULL");
    *out = NULL;
    const sl_allocator *a = sl_alloc_or_default(alloc);
    for (uint32_t i = 0; i < count; i++) {
        sl_status st = sl_viewcell_validate(&cells[i], i, err);
        if (st != SL_OK)
            return st;
    }
    sl_viewcell *copy = sl_alloc(a, (count ? count : 1) * sizeof *copy);
    if (!copy)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "view cells: out of memory for %u cells", count);
    if (count)
        memcpy(copy, cells, (size_t)count * sizeof *copy);
    /* make_cells frees `copy` with count entries: keep the size consistent for count 0 */
    if (!count) {
        sl_free(a, copy, sizeof *copy);
        copy = NULL;
    }
    return make_cells(a, copy, count, out, err);
}

uint32_t sl_viewcells_count(sl_viewcells v) { return v ? v->count : 0; }

const sl_viewcell *sl_viewcells_data(sl_viewcells v) { return v ? v->cells : NULL; }

uint64_t sl_viewcells_key(sl_viewcells v) { return v ? v->key : 0; }

static bool in_box(const sl_aabb *b, sl_vec3 p)
{
    return p.x >= b->min.x && p.x <= b->max.x && p.y >= b->min.y && p.y <= b->max.y && p.z >= b->min.z &&
           p.z <= b->max.z;
}

static bool cluster_of_point(sl_scene scene, sl_vec3 p, int32_t *cluster)
{
    if (!scene)
        return false;
    sl_bsp_view bsp;
    if (!sl_scene_bsp(scene, &bsp))
        return false;
    int32_t leaf = sl_scene_bsp_find_leaf(scene, p);
    if (leaf < 0 || (uint32_t)leaf >= bsp.leaf_count)
        return false;
    *cluster = bsp.leaves[leaf].cluster;
    return *cluster >= 0;
}

/* Containment for shapes that need no scene. */
static bool contains_geom(const sl_viewcell *c, sl_vec3 p)
{
    if (!in_box(&c->bounds, p))
        return false;
    if (c->shape == SL_CELL_BOX)
        return true;
    if (c->shape != SL_CELL_PRISM)
        return false;
    const sl_vec2 *t = c->tri;
    return sl_orient2d(t[0].x, t[0].y, t[1].x, t[1].y, p.x, p.y) >= 0 &&
           sl_orient2d(t[1].x, t[1].y, t[2].x, t[2].y, p.x, p.y) >= 0 &&
           sl_orient2d(t[2].x, t[2].y, t[0].x, t[0].y, p.x, p.y) >= 0;
}

bool sl_viewcell_contains(sl_viewcells v, sl_scene scene, uint32_t cell, sl_vec3 p)
{
    if (!v || cell >= v->count || !sl_finite3(&p.x))
        return false;
    const sl_viewcell *c = &v->cells[cell];
    if (c->shape == SL_CELL_CLUSTER) {
        int32_t cl;
        return in_box(&c->bounds, p) && cluster_of_point(scene, p, &cl) && cl == c->cluster;
    }
    return contains_geom(c, p);
}

uint32_t sl_viewcells_locate(sl_viewcells v, sl_scene scene, sl_vec3 p)
{
    if (!v || v->count == 0 || !sl_finite3(&p.x))
        return SL_NONE;
    if (v->cluster_map) {
        int32_t cl;
        if (cluster_of_point(scene, p, &cl) && (uint32_t)cl < v->cluster_span) {
            uint32_t cell = v->cluster_map[cl];
            if (cell != SL_NONE && in_box(&v->cells[cell].bounds, p))
                return cell;
        }
    }
    /* every cell containing p is visited; the lowest id wins, so the answer does not depend on
     * the tree's shape */
    uint32_t best = SL_NONE;
    uint32_t stack[SL_VC_MAX_DEPTH + 1], sp = 0, ni = 0;
    for (;;) {
        const sl_vc_node *n = &v->nodes[ni];
        if (in_box(&n->box, p)) {
            if (n->count == 0) {
                stack[sp++] = n->first;
                ni = ni + 1;
                continue;
            }
            for (uint32_t k = n->first; k < n->first + n->count; k++) {
                uint32_t id = v->order[k];
                if (id < best && v->cells[id].shape != SL_CELL_CLUSTER && contains_geom(&v->cells[id], p))
                    best = id;
            }
        }
        if (sp == 0)
            break;
        ni = stack[--sp];
    }
    return best;
}

/* ---- cells meeting a box (the pvs culler's near-plane region) -------------------------------- */

static bool boxes_meet(const sl_aabb *a, const sl_aabb *b)
{
    return a->min.x <= b->max.x && a->max.x >= b->min.x && a->min.y <= b->max.y && a->max.y >= b->min.y &&
           a->min.z <= b->max.z && a->max.z >= b->min.z;
}

/* Insert id into the ascending list out[0..*n) (no repeats); false when it does not fit. */
static bool insert_sorted(uint32_t *out, uint32_t capacity, uint32_t *n, uint32_t id)
{
    uint32_t lo = 0, hi = *n;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (out[mid] < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < *n && out[lo] == id)
        return true;
    if (*n >= capacity)
        return false;
    memmove(out + lo + 1, out + lo, (size_t)(*n - lo) * sizeof *out);
    out[lo] = id;
    (*n)++;
    return true;
}

/* XY area of triangle t clipped to the rectangle [x0,x1] x [y0,y1] (Sutherland-Hodgman). */
static double tri_rect_area(const sl_vec2 t[3], double x0, double y0, double x1, double y1)
{
    double a[2][16];
    double b[2][16];
    uint32_t n = 3;
    for (int i = 0; i < 3; i++) {
        a[0][i] = t[i].x;
        a[1][i] = t[i].y;
    }
    for (int side = 0; side < 4; side++) {
        int axis = side >> 1;
        double lim = side == 0 ? x0 : side == 1 ? x1 : side == 2 ? y0 : y1;
        double sgn = (side & 1) ? -1.0 : 1.0; /* inside: sgn * (coord - lim) >= 0 */
        uint32_t m = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t j = (i + 1) % n;
            double di = sgn * (a[axis][i] - lim), dj = sgn * (a[axis][j] - lim);
            if (di >= 0) {
                b[0][m] = a[0][i];
                b[1][m] = a[1][i];
                m++;
            }
            if ((di >= 0) != (dj >= 0)) {
                double u = di / (di - dj);
                b[0][m] = a[0][i] + u * (a[0][j] - a[0][i]);
                b[1][m] = a[1][i] + u * (a[1][j] - a[1][i]);
                m++;
            }
        }
        n = m;
        if (n < 3)
            return 0;
        memcpy(a, b, sizeof a);
    }
    double area = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        area += a[0][i] * a[1][j] - a[0][j] * a[1][i];
    }
    return fabs(area) * 0.5;
}

/* Volume of the part of cell c (PRISM or BOX) inside box q. */
static double cell_box_volume(const sl_viewcell *c, const sl_aabb *q)
{
    double z0 = fmax(c->bounds.min.z, q->min.z), z1 = fmin(c->bounds.max.z, q->max.z);
    if (z1 <= z0)
        return 0;
    double area;
    if (c->shape == SL_CELL_BOX) {
        double w = fmin(c->bounds.max.x, q->max.x) - fmax(c->bounds.min.x, q->min.x);
        double h = fmin(c->bounds.max.y, q->max.y) - fmax(c->bounds.min.y, q->min.y);
        area = w > 0 && h > 0 ? w * h : 0;
    } else {
        area = tri_rect_area(c->tri, q->min.x, q->min.y, q->max.x, q->max.y);
    }
    return area * (z1 - z0);
}

#define SL_VC_BSP_STACK 512u

uint32_t sl_viewcells_overlap(sl_viewcells v, sl_scene scene, const sl_aabb *box, uint32_t *out, uint32_t capacity,
                              bool *covered)
{
    bool cov = false;
    uint32_t n = 0;
    if (covered)
        *covered = false;
    if (!v || v->count == 0 || !box || !sl_finite3(&box->min.x) || !sl_finite3(&box->max.x) ||
        box->min.x > box->max.x || box->min.y > box->max.y || box->min.z > box->max.z)
        return 0;
    bool fits = true;
    sl_bsp_view bsp;
    if (v->cluster_map && scene && sl_scene_bsp(scene, &bsp)) {
        /* every leaf the box meets, through the BSP tree; a leaf without a cluster (solid or void),
         * or without a cell, leaves the box uncovered */
        cov = true;
        int32_t stack[SL_VC_BSP_STACK];
        uint32_t sp = 0;
        stack[sp++] = bsp.node_count ? 0 : -1;
        while (sp) {
            int32_t nd = stack[--sp];
            if (nd < 0) {
                uint32_t leaf = (uint32_t)(-(nd + 1));
                if (leaf >= bsp.leaf_count) {
                    cov = false;
                    continue;
                }
                int32_t cl = bsp.leaves[leaf].cluster;
                uint32_t cell = cl >= 0 && (uint32_t)cl < v->cluster_span ? v->cluster_map[cl] : SL_NONE;
                if (cell == SL_NONE) {
                    cov = false;
                    continue;
                }
                if (!insert_sorted(out, capacity, &n, cell))
                    fits = false;
                continue;
            }
            const sl_bsp_node *node = &bsp.nodes[nd];
            const sl_plane *pl = &bsp.planes[node->plane];
            /* the plane's extreme values over the box (float, as sl_scene_bsp_find_leaf; a margin
             * covers the rounding) */
            double c = (double)pl->a * (0.5 * ((double)box->min.x + box->max.x)) +
                       (double)pl->b * (0.5 * ((double)box->min.y + box->max.y)) +
                       (double)pl->c * (0.5 * ((double)box->min.z + box->max.z)) + pl->d;
            double r = fabs((double)pl->a) * 0.5 * ((double)box->max.x - box->min.x) +
                       fabs((double)pl->b) * 0.5 * ((double)box->max.y - box->min.y) +
                       fabs((double)pl->c) * 0.5 * ((double)box->max.z - box->min.z);
            double slack = SL_MARGIN_PLANE_REL * (fabs((double)pl->d) + 1.0);
            if (sp + 2 > SL_VC_BSP_STACK) {
                cov = false; /* deeper than the stack: say uncovered (the caller falls back) */
                fits = false;
                break;
            }
            if (c + r + slack >= 0)
                stack[sp++] = node->children[0];
            if (c - r - slack < 0)
                stack[sp++] = node->children[1];
        }
    }
    /* the other shapes through the cell tree; coverage by volume (cells do not overlap) */
    double vol = 0;
    bool others = false;
    uint32_t tstack[SL_VC_MAX_DEPTH + 1], sp = 0, ni = 0;
    for (;;) {
        const sl_vc_node *nn = &v->nodes[ni];
        if (boxes_meet(&nn->box, box)) {
            if (nn->count == 0) {
                tstack[sp++] = nn->first;
                ni = ni + 1;
                continue;
            }
            for (uint32_t k = nn->first; k < nn->first + nn->count; k++) {
                uint32_t id = v->order[k];
                const sl_viewcell *c = &v->cells[id];
                if (c->shape == SL_CELL_CLUSTER || !boxes_meet(&c->bounds, box))
                    continue;
                double cv = cell_box_volume(c, box);
                /* every cell whose box meets the query box is taken (a superset of the cells it
                 * touches: conservative for the caller) */
                others = true;
                vol += cv;
                if (!insert_sorted(out, capacity, &n, id))
                    fits = false;
            }
        }
        if (sp == 0)
            break;
        ni = tstack[--sp];
    }
    if (others && !v->cluster_map) {
        double bv = ((double)box->max.x - box->min.x) * ((double)box->max.y - box->min.y) *
                    ((double)box->max.z - box->min.z);
        cov = bv > 0 ? vol >= bv * (1.0 - 1e-6) : true;
    }
    if (covered)
        *covered = cov && fits;
    return n;
}

void sl_viewcells_get_stats(sl_viewcells v, sl_viewcells_stats *out)
{
    if (!out)
        return;
    memset(out, 0, sizeof *out);
    if (!v)
        return;
    out->count = v->count;
    out->min_edge = INFINITY;
    out->min_angle_deg = 180;
    for (uint32_t i = 0; i < v->count; i++) {
        const sl_viewcell *c = &v->cells[i];
        if (c->shape == SL_CELL_PRISM) {
            out->prisms++;
            const sl_vec2 *t = c->tri;
            out->area += 0.5 * sl_orient2d(t[0].x, t[0].y, t[1].x, t[1].y, t[2].x, t[2].y);
            double len[3];
            for (int e = 0; e < 3; e++) {
                const sl_vec2 *a = &t[e], *b = &t[(e + 1) % 3];
                len[e] = hypot((double)b->x - a->x, (double)b->y - a->y);
                out->min_edge = fmin(out->min_edge, len[e]);
                out->max_edge = fmax(out->max_edge, len[e]);
            }
            for (int k = 0; k < 3; k++) {
                /* angle at vertex k, opposite edge (k+1)%3, by the law of cosines */
                double a = len[(k + 1) % 3], b = len[k], c2 = len[(k + 2) % 3];
                double cosv = (b * b + c2 * c2 - a * a) / (2 * b * c2);
                out->min_angle_deg = fmin(out->min_angle_deg, acos(fmax(-1.0, fmin(1.0, cosv))) * 180.0 / M_PI);
            }
        } else if (c->shape == SL_CELL_BOX) {
            out->boxes++;
            double w = (double)c->bounds.max.x - c->bounds.min.x, h = (double)c->bounds.max.y - c->bounds.min.y;
            out->area += w * h;
            out->min_edge = fmin(out->min_edge, fmin(w, h));
            out->max_edge = fmax(out->max_edge, fmax(w, h));
        } else {
            out->clusters++;
        }
    }
    if (!isfinite(out->min_edge))
        out->min_edge = 0;
    if (out->prisms == 0)
        out->min_angle_deg = 0;
}

/* ============================================================================================
 * Ground heights
 * ============================================================================================ */

void sl_ground_range(sl_scene scene, double x0, double y0, double x1, double y1, float *lo, float *hi)
{
    sl_terrain_view t;
    if (!sl_scene_terrain(scene, &t)) {
        *lo = *hi = 0;
        return;
    }
    /* sample indices of the squares meeting the box, clamped like sl_scene_ground_height */
    double fx0 = (x0 - t.origin_x) / t.cell, fx1 = (x1 - t.origin_x) / t.cell;
    double fy0 = (y0 - t.origin_y) / t.cell, fy1 = (y1 - t.origin_y) / t.cell;
    int64_t i0 = (int64_t)floor(fmax(0.0, fmin(fx0, (double)t.nx - 1)));
    int64_t i1 = (int64_t)ceil(fmax(0.0, fmin(fx1, (double)t.nx - 1)));
    int64_t j0 = (int64_t)floor(fmax(0.0, fmin(fy0, (double)t.ny - 1)));
    int64_t j1 = (int64_t)ceil(fmax(0.0, fmin(fy1, (double)t.ny - 1)));
    float l = INFINITY, h = -INFINITY;
    for (int64_t j = j0; j <= j1; j++)
        for (int64_t i = i0; i <= i1; i++) {
            float z = t.heights[(size_t)j * t.nx + (size_t)i];
            l = fminf(l, z);
            h = fmaxf(h, z);
        }
    *lo = l;
    *hi = h;
}

static void fill_prism(sl_scene scene, const double tri[6], float eye_min, float eye_max, sl_viewcell *c)
{
    memset(c, 0, sizeof *c);
    c->shape = SL_CELL_PRISM;
    c->cluster = -1;
    for (int k = 0; k < 3; k++) {
        c->tri[k].x = (float)tri[2 * k];
        c->tri[k].y = (float)tri[2 * k + 1];
    }
    sl_aabb b = prism_bounds(c);
    float lo, hi;
    sl_ground_range(scene, b.min.x, b.min.y, b.max.x, b.max.y, &lo, &hi);
    c->z_min = lo + eye_min;
    c->z_max = hi + eye_max;
    c->bounds = prism_bounds(c);
}

static void fill_box(sl_viewcell *c, sl_aabb b)
{
    memset(c, 0, sizeof *c);
    c->shape = SL_CELL_BOX;
    c->cluster = -1;
    c->z_min = b.min.z;
    c->z_max = b.max.z;
    c->bounds = b;
}

/* ============================================================================================
 * Options
 * ============================================================================================ */

typedef struct resolved {
    float max_edge, min_edge, eye_min, eye_max;
    uint32_t max_cells;
    const sl_allocator *alloc;
    const sl_progress *progress;
} resolved;

static sl_status resolve(const sl_viewcell_options *opt, float def_edge, resolved *r, const char *who, sl_error *err)
{
    sl_viewcell_options o;
    if (opt)
        o = *opt;
    else
        memset(&o, 0, sizeof o);
    if (isnan(o.max_edge) || isnan(o.min_edge) || o.max_edge < 0 || o.min_edge < 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: max_edge %g and min_edge %g must be positive (0: default)",
                       who, (double)o.max_edge, (double)o.min_edge);
    r->max_edge = o.max_edge > 0 ? o.max_edge : def_edge;
    r->min_edge = o.min_edge > 0 ? o.min_edge : fminf(DEFAULT_ADAPTIVE_MIN, r->max_edge);
    r->eye_min = o.eye_min != 0 ? o.eye_min : DEFAULT_EYE_MIN;
    r->eye_max = o.eye_max != 0 ? o.eye_max : DEFAULT_EYE_MAX;
    r->max_cells = o.max_cells ? o.max_cells : DEFAULT_MAX_CELLS;
    r->alloc = sl_alloc_or_default(o.alloc);
    r->progress = opt ? &opt->progress : NULL;
    if (!isfinite(r->max_edge) || !(r->max_edge >= 0.01f) || !(r->max_edge <= 1e5f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: max_edge %g is outside [0.01, 100000] m", who,
                       (double)r->max_edge);
    if (!isfinite(r->min_edge) || !(r->min_edge >= 0.001f) || r->min_edge > r->max_edge)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: min_edge %g must lie in [0.001, max_edge %g]", who,
                       (double)r->min_edge, (double)r->max_edge);
    if (!isfinite(r->eye_min) || !isfinite(r->eye_max) || !(r->eye_min <= r->eye_max) || fabsf(r->eye_max) > 1e4f)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: eye heights %g..%g are not an interval of finite heights",
                       who, (double)r->eye_min, (double)r->eye_max);
    return SL_OK;
}

/* ============================================================================================
 * Street cells (constrained triangulation of the free space)
 * ============================================================================================ */

typedef struct tri_sink {
    const sl_allocator *a;
    sl_scene scene;
    const resolved *r;
    sl_array cells; /* sl_viewcell */
    double *xy;
    size_t xy_cap;
    sl_geos *g;
    bool oom, limit;
} tri_sink;

/* Split a triangle at the midpoint of its longest edge until no edge exceeds max_edge, emitting
 * the pieces as cells (counter-clockwise). */
static void emit_refined(tri_sink *s, const double t0[6])
{
    double stack[64][6];
    int sp = 0;
    memcpy(stack[sp++], t0, sizeof stack[0]);
    double lim2 = (double)s->r->max_edge * s->r->max_edge;
    while (sp > 0 && !s->oom && !s->limit) {
        double t[6];
        memcpy(t, stack[--sp], sizeof t);
        int longest = 0;
        double l2max = -1;
        for (int e = 0; e < 3; e++) {
            int f = (e + 1) % 3;
            double dx = t[2 * f] - t[2 * e], dy = t[2 * f + 1] - t[2 * e + 1];
            double l2 = dx * dx + dy * dy;
            if (l2 > l2max) {
                l2max = l2;
                longest = e;
            }
        }
        if (l2max > lim2 && sp + 2 <= 64) {
            /* midpoint m of edge (e, f); children (e, m, g) and (m, f, g) keep the orientation */
            int e = longest, f = (e + 1) % 3, gi = (e + 2) % 3;
            double mx = 0.5 * (t[2 * e] + t[2 * f]), my = 0.5 * (t[2 * e + 1] + t[2 * f + 1]);
            double a[6] = {t[2 * e], t[2 * e + 1], mx, my, t[2 * gi], t[2 * gi + 1]};
            double b[6] = {mx, my, t[2 * f], t[2 * f + 1], t[2 * gi], t[2 * gi + 1]};
            memcpy(stack[sp++], b, sizeof b);
            memcpy(stack[sp++], a, sizeof a);
            continue;
        }
        sl_viewcell c;
        fill_prism(s->scene, t, s->r->eye_min, s->r->eye_max, &c);
        /* float rounding can flatten a sliver: such a cell holds no point worth keeping */
        if (!(sl_orient2d(c.tri[0].x, c.tri[0].y, c.tri[1].x, c.tri[1].y, c.tri[2].x, c.tri[2].y) > 0))
            continue;
        if (s->cells.count >= s->r->max_cells) {
            s->limit = true;
            return;
        }
        if (!sl_array_push(s->a, &s->cells, sizeof c, &c, 1))
            s->oom = true;
    }
}

/* One triangle of GEOS's output. */
static bool take_triangle(void *user, const GEOSGeometry *poly)
{
    tri_sink *s = user;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(s->g->h, poly);
    int n = ring ? sl_geos_ring_coords(s->g, ring, s->a, &s->xy, &s->xy_cap) : -1;
    if (n != 3) {
        s->oom = n < 0;
        return n >= 0; /* not a triangle: skip it */
    }
    double t[6];
    memcpy(t, s->xy, sizeof t);
    double o = sl_orient2d(t[0], t[1], t[2], t[3], t[4], t[5]);
    if (o == 0)
        return true;
    if (o < 0) {
        double x = t[2], y = t[3];
        t[2] = t[4], t[3] = t[5], t[4] = x, t[5] = y;
    }
    emit_refined(s, t);
    return !s->oom && !s->limit;
}

typedef struct poly_ctx {
    tri_sink *sink;
    uint32_t done, total;
    sl_status st;
    sl_error *err;
} poly_ctx;

/* Triangulate one polygon of the free space: densified to the maximum edge first. GEOS's ear
 * clipping can fail on near-degenerate input ("unable to find a convex corner"); the polygon is then
 * triangulated undensified (the longest-edge splits refine it all the same), and last snapped to a
 * millimetre grid. */
static bool triangulate_polygon(void *user, const GEOSGeometry *poly)
{
    poly_ctx *p = user;
    sl_geos *g = p->sink->g;
    GEOSGeometry *tris = NULL;
    GEOSGeometry *dense = GEOSDensify_r(g->h, poly, p->sink->r->max_edge);
    if (dense) {
        tris = GEOSConstrainedDelaunayTriangulation_r(g->h, dense);
        GEOSGeom_destroy_r(g->h, dense);
    }
    if (!tris)
        tris = GEOSConstrainedDelaunayTriangulation_r(g->h, poly);
    if (!tris) {
        GEOSGeometry *snapped = GEOSGeom_setPrecision_r(g->h, poly, 1e-3, 0);
        if (snapped) {
            tris = GEOSConstrainedDelaunayTriangulation_r(g->h, snapped);
            GEOSGeom_destroy_r(g->h, snapped);
        }
    }
    if (!tris) {
        p->st = sl_fail(p->err, SL_ERROR_INTERNAL, "view cells: GEOS could not triangulate free-space polygon %u: %s",
                        p->done, g->message);
        return false;
    }
    bool ok = sl_geos_each_polygon(g, tris, take_triangle, p->sink);
    GEOSGeom_destroy_r(g->h, tris);
    p->done++;
    if (!ok)
        return false;
    if (!sl_progress_report(p->sink->r->progress, "view cells", p->done, p->total)) {
        p->st = sl_fail(p->err, SL_ERROR_CANCELLED, "view cells: cancelled");
        return false;
    }
    return true;
}

/* Union of the street polygons (valid parts only) minus the footprints. */
static GEOSGeometry *free_space(sl_geos *g, const sl_allocator *a, sl_scene scene, sl_error *err, sl_status *st)
{
    uint32_t ns = sl_scene_street_polygon_count(scene), nf = sl_scene_footprint_count(scene);
    size_t parts_size = ((size_t)SL_MAX(ns, nf) + 1) * sizeof(GEOSGeometry *);
    GEOSGeometry **parts = sl_alloc(a, parts_size);
    if (!parts) {
        *st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "view cells: out of memory");
        return NULL;
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i < ns; i++) {
        sl_polygon_view pv = sl_scene_street_polygon(scene, i);
        GEOSGeometry *p = sl_geos_polygon(g, pv.xy, pv.vertex_count);
        if (p && !GEOSisValid_r(g->h, p)) {
            GEOSGeometry *fixed = GEOSMakeValid_r(g->h, p);
            GEOSGeom_destroy_r(g->h, p);
            p = fixed;
        }
        if (p)
            parts[k++] = p;
    }
    GEOSGeometry *coll = GEOSGeom_createCollection_r(g->h, GEOS_GEOMETRYCOLLECTION, parts, k);
    GEOSGeometry *space = coll ? GEOSUnaryUnion_r(g->h, coll) : NULL;
    if (coll)
        GEOSGeom_destroy_r(g->h, coll);
    else
        for (uint32_t i = 0; i < k; i++)
            GEOSGeom_destroy_r(g->h, parts[i]);
    if (!space) {
        sl_free(a, parts, parts_size);
        *st = sl_fail(err, SL_ERROR_INTERNAL, "view cells: GEOS could not unite the street polygons: %s", g->message);
        return NULL;
    }
    k = 0;
    for (uint32_t i = 0; i < nf; i++) {
        sl_footprint_view fv = sl_scene_footprint(scene, i);
        GEOSGeometry *p = sl_geos_polygon(g, fv.xy, fv.vertex_count);
        if (p)
            parts[k++] = p;
    }
    if (k > 0) {
        GEOSGeometry *fcoll = GEOSGeom_createCollection_r(g->h, GEOS_GEOMETRYCOLLECTION, parts, k);
        GEOSGeometry *fu = fcoll ? GEOSUnaryUnion_r(g->h, fcoll) : NULL;
        if (fcoll)
            GEOSGeom_destroy_r(g->h, fcoll);
        else
            for (uint32_t i = 0; i < k; i++)
                GEOSGeom_destroy_r(g->h, parts[i]);
        GEOSGeometry *diff = fu ? GEOSDifference_r(g->h, space, fu) : NULL;
        if (fu)
            GEOSGeom_destroy_r(g->h, fu);
        GEOSGeom_destroy_r(g->h, space);
        space = diff;
        if (!space) {
            sl_free(a, parts, parts_size);
            *st = sl_fail(err, SL_ERROR_INTERNAL, "view cells: GEOS could not subtract the footprints: %s", g->message);
            return NULL;
        }
    }
    sl_free(a, parts, parts_size);
    return space;
}

sl_status sl_viewcells_from_streets(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_from_streets: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_STREET_EDGE, &r, "street view cells", err);
    if (st != SL_OK)
        return st;
    if (sl_scene_street_polygon_count(scene) == 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "street view cells: the scene has no street polygons (use grid, adaptive or bsp cells)");
    sl_geos g;
    if (!sl_geos_init(&g))
        return sl_fail(err, SL_ERROR_INTERNAL, "street view cells: GEOS could not start");
    tri_sink sink;
    memset(&sink, 0, sizeof sink);
    sink.a = r.alloc;
    sink.scene = scene;
    sink.r = &r;
    sink.g = &g;
    GEOSGeometry *space = free_space(&g, r.alloc, scene, err, &st);
    if (space) {
        poly_ctx pc = {&sink, 0, (uint32_t)SL_MAX(GEOSGetNumGeometries_r(g.h, space), 1), SL_OK, err};
        sl_geos_each_polygon(&g, space, triangulate_polygon, &pc);
        st = pc.st;
        if (st == SL_OK && sink.oom)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street view cells: out of memory after %zu cells", sink.cells.count);
        if (st == SL_OK && sink.limit)
            st = sl_fail(err, SL_ERROR_LIMIT, "street view cells: more than %u cells (raise max_cells or max_edge)",
                         r.max_cells);
        GEOSGeom_destroy_r(g.h, space);
    }
    sl_geos_finish(&g);
    sl_free(r.alloc, sink.xy, sink.xy_cap * sizeof(double));
    if (st == SL_OK && sink.cells.count == 0)
        st = sl_fail(err, SL_ERROR_UNSUPPORTED, "street view cells: the free space has no area");
    if (st != SL_OK) {
        sl_array_free(r.alloc, &sink.cells, sizeof(sl_viewcell));
        return st;
    }
    /* shrink the array to its count so that the container frees exactly what it holds */
    sl_viewcell *cells = sl_realloc(r.alloc, sink.cells.data, sink.cells.cap * sizeof(sl_viewcell),
                                    sink.cells.count * sizeof(sl_viewcell));
    if (!cells) {
        sl_array_free(r.alloc, &sink.cells, sizeof(sl_viewcell));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street view cells: out of memory");
    }
    return make_cells(r.alloc, cells, (uint32_t)sink.cells.count, out, err);
}

/* ============================================================================================
 * Grid cells
 * ============================================================================================ */

static sl_status finish_array(const sl_allocator *a, sl_array *arr, sl_viewcells *out, const char *who, sl_error *err)
{
    if (arr->count == 0) {
        sl_array_free(a, arr, sizeof(sl_viewcell));
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: no cells", who);
    }
    sl_viewcell *cells = sl_realloc(a, arr->data, arr->cap * sizeof(sl_viewcell), arr->count * sizeof(sl_viewcell));
    if (!cells) {
        sl_array_free(a, arr, sizeof(sl_viewcell));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", who);
    }
    return make_cells(a, cells, (uint32_t)arr->count, out, err);
}

sl_status sl_viewcells_grid(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_grid: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_GRID_EDGE, &r, "grid view cells", err);
    if (st != SL_OK)
        return st;
    uint32_t ns = sl_scene_street_polygon_count(scene);
    sl_aabb ext = sl_aabb_empty();
    for (uint32_t i = 0; i < ns; i++) {
        sl_polygon_view pv = sl_scene_street_polygon(scene, i);
        for (uint32_t k = 0; k < pv.vertex_count; k++)
            sl_aabb_grow(&ext, (sl_vec3){pv.xy[2 * k], pv.xy[2 * k + 1], 0});
    }
    if (ns == 0)
        ext = sl_scene_bounds(scene);
    if (sl_aabb_is_empty(&ext))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "grid view cells: the scene is empty");
    double s = r.max_edge;
    double nxd = ceil(((double)ext.max.x - ext.min.x) / s), nyd = ceil(((double)ext.max.y - ext.min.y) / s);
    nxd = fmax(nxd, 1);
    nyd = fmax(nyd, 1);
    if (nxd * nyd > (double)r.max_cells * 4.0 || nxd * nyd > 1e9)
        return sl_fail(err, SL_ERROR_LIMIT, "grid view cells: %.0f x %.0f cells of %g m is too many (max_cells %u)",
                       nxd, nyd, s, r.max_cells);
    uint32_t nx = (uint32_t)nxd, ny = (uint32_t)nyd;
    sl_geos g;
    GEOSGeometry *space = NULL;
    const GEOSPreparedGeometry *prep = NULL;
    if (ns > 0) {
        if (!sl_geos_init(&g))
            return sl_fail(err, SL_ERROR_INTERNAL, "grid view cells: GEOS could not start");
        space = free_space(&g, r.alloc, scene, err, &st);
        prep = space ? GEOSPrepare_r(g.h, space) : NULL;
        if (space && !prep)
            st = sl_fail(err, SL_ERROR_INTERNAL, "grid view cells: GEOS could not prepare the free space: %s",
                         g.message);
    }
    sl_array arr = {0};
    for (uint32_t j = 0; j < ny && st == SL_OK; j++) {
        for (uint32_t i = 0; i < nx && st == SL_OK; i++) {
            double x0 = ext.min.x + i * s, y0 = ext.min.y + j * s, x1 = x0 + s, y1 = y0 + s;
            if (prep) {
                GEOSGeometry *rect = GEOSGeom_createRectangle_r(g.h, x0, y0, x1, y1);
                char hit = rect ? GEOSPreparedIntersects_r(g.h, prep, rect) : 2;
                if (rect)
                    GEOSGeom_destroy_r(g.h, rect);
                if (hit == 2) {
                    st = sl_fail(err, SL_ERROR_INTERNAL, "grid view cells: GEOS failed on cell (%u, %u): %s", i, j,
                                 g.message);
                    break;
                }
                if (!hit)
                    continue;
            }
            float lo, hi;
            sl_ground_range(scene, x0, y0, x1, y1, &lo, &hi);
            sl_aabb b = {{(float)x0, (float)y0, lo + r.eye_min}, {(float)x1, (float)y1, hi + r.eye_max}};
            sl_viewcell c;
            fill_box(&c, b);
            if (arr.count >= r.max_cells)
                st = sl_fail(err, SL_ERROR_LIMIT, "grid view cells: more than %u cells", r.max_cells);
            else if (!sl_array_push(r.alloc, &arr, sizeof c, &c, 1))
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "grid view cells: out of memory");
        }
        if (st == SL_OK && !sl_progress_report(r.progress, "view cells", j + 1, ny))
            st = sl_fail(err, SL_ERROR_CANCELLED, "grid view cells: cancelled");
    }
    if (ns > 0) {
        if (prep)
            GEOSPreparedGeom_destroy_r(g.h, prep);
        if (space)
            GEOSGeom_destroy_r(g.h, space);
        sl_geos_finish(&g);
    }
    if (st != SL_OK) {
        sl_array_free(r.alloc, &arr, sizeof(sl_viewcell));
        return st;
    }
    return finish_array(r.alloc, &arr, out, "grid view cells", err);
}

/* ============================================================================================
 * Quake III clusters
 * ============================================================================================ */

sl_status sl_viewcells_from_bsp(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_from_bsp: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_GRID_EDGE, &r, "bsp view cells", err);
    if (st != SL_OK)
        return st;
    sl_bsp_view bsp;
    if (!sl_scene_bsp(scene, &bsp))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "bsp view cells: the scene has no BSP data (not a Quake III map)");
    if (bsp.cluster_count == 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "bsp view cells: the map has no clusters");
    if (bsp.cluster_count > SL_VC_MAX_CLUSTER)
        return sl_fail(err, SL_ERROR_LIMIT, "bsp view cells: %u clusters (at most %d)", bsp.cluster_count,
                       SL_VC_MAX_CLUSTER);
    sl_aabb *boxes = sl_alloc(r.alloc, bsp.cluster_count * sizeof(sl_aabb));
    if (!boxes)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bsp view cells: out of memory");
    for (uint32_t c = 0; c < bsp.cluster_count; c++)
        boxes[c] = sl_aabb_empty();
    for (uint32_t l = 0; l < bsp.leaf_count; l++) {
        int32_t c = bsp.leaves[l].cluster;
        if (c >= 0 && (uint32_t)c < bsp.cluster_count && !sl_aabb_is_empty(&bsp.leaves[l].bounds))
            sl_aabb_merge(&boxes[c], &bsp.leaves[l].bounds);
    }
    sl_array arr = {0};
    for (uint32_t c = 0; c < bsp.cluster_count && st == SL_OK; c++) {
        if (sl_aabb_is_empty(&boxes[c]))
            continue;
        sl_viewcell cell;
        fill_box(&cell, boxes[c]);
        cell.shape = SL_CELL_CLUSTER;
        cell.cluster = (int32_t)c;
        if (!sl_array_push(r.alloc, &arr, sizeof cell, &cell, 1))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bsp view cells: out of memory");
    }
    sl_free(r.alloc, boxes, bsp.cluster_count * sizeof(sl_aabb));
    if (st != SL_OK) {
        sl_array_free(r.alloc, &arr, sizeof(sl_viewcell));
        return st;
    }
    return finish_array(r.alloc, &arr, out, "bsp view cells", err);
}

/* ============================================================================================
 * Adaptive subdivision of a navigable volume
 * ============================================================================================ */

typedef struct adapt {
    const resolved *r;
    sl_scene scene;
    sl_bvh bvh;
    uint32_t object;            /* the volume's own object (not an obstacle), or SL_NONE */
    /* world-space triangles of the volume mesh, 9 floats each (NULL: box volume) */
    float *tris;
    uint32_t tri_count;
    sl_array cells;
    sl_status st;
    sl_error *err;
} adapt;

/* Ray parity along a fixed skewed direction: inside a closed mesh when odd. */
static bool inside_mesh(const adapt *ad, sl_vec3 p)
{
    const double d[3] = {0.8727, 0.3141, 0.3737}; /* skewed so that it grazes no axis-aligned edge */
    uint32_t hits = 0;
    for (uint32_t k = 0; k < ad->tri_count; k++) {
        const float *t = ad->tris + 9 * k;
        double e1[3], e2[3], s[3];
        for (int i = 0; i < 3; i++) {
            e1[i] = (double)t[3 + i] - t[i];
            e2[i] = (double)t[6 + i] - t[i];
            s[i] = (double)(&p.x)[i] - t[i];
        }
        double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
        double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (fabs(det) < 1e-18)
            continue;
        double u = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) / det;
        if (u < 0 || u > 1)
            continue;
        double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
        double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
        if (v < 0 || u + v > 1)
            continue;
        double t_hit = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
        if (t_hit > 0)
            hits++;
    }
    return hits & 1;
}

static bool meets_obstacle(const adapt *ad, const sl_aabb *b)
{
    if (!ad->bvh)
        return false;
    uint32_t ids[2];
    uint32_t n = sl_bvh_query_aabb(ad->bvh, b, ids, 2);
    if (n == 0)
        return false;
    if (n >= 2 || ids[0] != ad->object)
        return true;
    return false;
}

static void subdivide(adapt *ad, sl_aabb b, uint32_t depth)
{
    if (ad->st != SL_OK)
        return;
    float ext[3] = {b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z};
    int axis = ext[1] > ext[0] ? 1 : 0;
    if (ext[2] > ext[axis])
        axis = 2;
    float big = ext[axis];
    bool split = depth < 48 && (big > ad->r->max_edge || (big > ad->r->min_edge && meets_obstacle(ad, &b)));
    if (split) {
        sl_aabb lo = b, hi = b;
        float mid = 0.5f * ((&b.min.x)[axis] + (&b.max.x)[axis]);
        (&lo.max.x)[axis] = mid;
        (&hi.min.x)[axis] = mid;
        subdivide(ad, lo, depth + 1);
        subdivide(ad, hi, depth + 1);
        return;
    }
    if (ad->tris) {
        sl_vec3 c = {0.5f * (b.min.x + b.max.x), 0.5f * (b.min.y + b.max.y), 0.5f * (b.min.z + b.max.z)};
        if (!inside_mesh(ad, c))
            return;
    }
    if (ad->cells.count >= ad->r->max_cells) {
        ad->st = sl_fail(ad->err, SL_ERROR_LIMIT, "adaptive view cells: more than %u cells", ad->r->max_cells);
        return;
    }
    sl_viewcell c;
    fill_box(&c, b);
    if (!sl_array_push(ad->r->alloc, &ad->cells, sizeof c, &c, 1))
        ad->st = sl_fail(ad->err, SL_ERROR_OUT_OF_MEMORY, "adaptive view cells: out of memory");
}

sl_status sl_viewcells_adaptive(sl_scene scene, const sl_aabb *volume, uint32_t object, const sl_viewcell_options *opt,
                                sl_viewcells *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_viewcells_adaptive: scene and out must not be NULL");
    *out = NULL;
    resolved r;
    sl_status st = resolve(opt, DEFAULT_ADAPTIVE_EDGE, &r, "adaptive view cells", err);
    if (st != SL_OK)
        return st;
    adapt ad;
    memset(&ad, 0, sizeof ad);
    ad.r = &r;
    ad.scene = scene;
    ad.err = err;
    ad.object = SL_NONE;
    sl_aabb box;
    const struct sl_scene_t *s = scene;
    if (volume) {
        box = *volume;
        if (!sl_finite3(&box.min.x) || !sl_finite3(&box.max.x) || !(box.min.x < box.max.x) ||
            !(box.min.y < box.max.y) || !(box.min.z <= box.max.z))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "adaptive view cells: the volume box is empty or not finite");
    } else {
        if (object >= sl_scene_object_count(scene))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "adaptive view cells: object %u does not exist (%u objects)",
                           object, sl_scene_object_count(scene));
        ad.object = object;
        sl_object_view ov = sl_scene_object(scene, object);
        sl_mesh_view mv = sl_scene_mesh(scene, ov.mesh);
        box = ov.bounds;
        ad.tri_count = mv.triangle_count;
        ad.tris = sl_alloc(r.alloc, ((size_t)mv.triangle_count + 1) * 9 * sizeof(float));
        if (!ad.tris)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adaptive view cells: out of memory");
        for (uint32_t t = 0; t < mv.triangle_count; t++)
            for (int k = 0; k < 3; k++) {
                const float *v = mv.positions + 3 * (size_t)mv.indices[3 * t + k];
                sl_vec3 w = sl_affine_point(&ov.transform, (sl_vec3){v[0], v[1], v[2]});
                memcpy(ad.tris + 9 * (size_t)t + 3 * k, &w, sizeof w);
            }
        (void)s;
    }
    sl_bvh_options bo = {0};
    bo.alloc = r.alloc;
    bo.threads = 1;
    if (sl_scene_object_count(scene) > 0 && (st = sl_bvh_build(scene, &bo, &ad.bvh, err)) != SL_OK) {
        sl_free(r.alloc, ad.tris, ((size_t)ad.tri_count + 1) * 9 * sizeof(float));
        return st;
    }
    ad.st = SL_OK;
    subdivide(&ad, box, 0);
    sl_bvh_destroy(ad.bvh);
    sl_free(r.alloc, ad.tris, ((size_t)ad.tri_count + 1) * 9 * sizeof(float));
    if (ad.st != SL_OK) {
        sl_array_free(r.alloc, &ad.cells, sizeof(sl_viewcell));
        return ad.st;
    }
    return finish_array(r.alloc, &ad.cells, out, "adaptive view cells", err);
}

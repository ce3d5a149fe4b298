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
 * leaf. For disjoint cells a point meets O(1) boxes per level, so a lookup costs O(log n).
 *
 * This file is the run-time part (pvs layer: records, the container, the lookup); the generators
 * (streets with GEOS, grid, BSP clusters, adaptive) are in src/region/viewcell_gen.c. */
#include "viewcells_internal.h"

#include "scene/scene_internal.h"
#include "sightline/accel.h"

#include <math.h>
#include <stdlib.h>


/* ============================================================================================
 * Records, validation, the container
 * ============================================================================================ */

static bool finite_f(float v) { return isfinite(v); }

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
        sl_aabb b = sl_viewcell_prism_bounds(c);
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
sl_status sl_viewcells_adopt(const sl_allocator *a, sl_viewcell *cells, uint32_t count, sl_viewcells *out,
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
    return sl_viewcells_adopt(a, copy, count, out, err);
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

/* squared distance from (px, py) to segment a-b */
static double seg_dist2(double px, double py, sl_vec2 a, sl_vec2 b)
{
    double dx = (double)b.x - a.x, dy = (double)b.y - a.y, l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((px - a.x) * dx + (py - a.y) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double ex = px - (a.x + t * dx), ey = py - (a.y + t * dy);
    return ex * ex + ey * ey;
}

static double box_dist2(const sl_aabb *b, sl_vec3 p)
{
    double d = 0, q[3] = {p.x, p.y, p.z}, lo[3] = {b->min.x, b->min.y, b->min.z}, hi[3] = {b->max.x, b->max.y, b->max.z};
    for (int k = 0; k < 3; k++) {
        double e = q[k] < lo[k] ? lo[k] - q[k] : q[k] > hi[k] ? q[k] - hi[k] : 0;
        d += e * e;
    }
    return d;
}

uint32_t sl_viewcells_nearest(sl_viewcells v, sl_vec3 p, double *distance)
{
    if (distance)
        *distance = INFINITY;
    if (!v || !v->count || !sl_finite3(&p.x))
        return SL_NONE;
    uint32_t best = SL_NONE;
    double best2 = INFINITY;
    for (uint32_t i = 0; i < v->count; i++) {
        const sl_viewcell *c = &v->cells[i];
        double d2;
        if (c->shape == SL_CELL_PRISM) {
            const sl_vec2 *t = c->tri;
            bool inside = sl_orient2d(t[0].x, t[0].y, t[1].x, t[1].y, p.x, p.y) >= 0 &&
                          sl_orient2d(t[1].x, t[1].y, t[2].x, t[2].y, p.x, p.y) >= 0 &&
                          sl_orient2d(t[2].x, t[2].y, t[0].x, t[0].y, p.x, p.y) >= 0;
            double h2 = 0;
            if (!inside) {
                h2 = seg_dist2(p.x, p.y, t[0], t[1]);
                double e = seg_dist2(p.x, p.y, t[1], t[2]);
                h2 = e < h2 ? e : h2;
                e = seg_dist2(p.x, p.y, t[2], t[0]);
                h2 = e < h2 ? e : h2;
            }
            double vz = p.z < c->z_min ? (double)c->z_min - p.z : p.z > c->z_max ? p.z - (double)c->z_max : 0;
            d2 = h2 + vz * vz;
        } else {
            d2 = box_dist2(&c->bounds, p);
        }
        if (d2 < best2) {
            best2 = d2;
            best = i;
        }
    }
    if (distance)
        *distance = sqrt(best2);
    return best;
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

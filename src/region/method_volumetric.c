/* volumetric: conservative from-region visibility on a voxelised scene, after G. Schaufler,
 * J. Dorsey, X. Decoret, F. X. Sillion, "Conservative Volumetric Visibility with Occluder Fusion",
 * SIGGRAPH 2000 (sections 3 and 4: the discretisation, blocker extension, shaft occlusion and the
 * object test; docs/volumetric.md says what is followed and what is left out).
 *
 *  1. prepare: a uniform voxel grid over the scene's bounds (side `voxel`, or the smallest side
 *     that keeps the grid under `max_voxels`). A voxel is OPAQUE only when it lies entirely inside
 *     solid matter: inside the prism of a building footprint (its square inside the polygon, its
 *     height range inside [base, roof]); inside BSP leaves without a cluster (the region oracle's
 *     opaque space, Quake III); or inside a closed mesh (every edge shared by exactly two
 *     triangles in opposite directions; an object flagged SL_OBJECT_OCCLUDER that is not
 *     see-through, or a scene occluder mesh), through sl_shrink_mesh_voxels with eps 0 (voxels
 *     whose corners are inside and that no triangle crosses) and an exact coverage check. Open
 *     meshes are never solid. The opaque voxels are cut into boxes (greedy runs in x, then y,
 *     then z): the blocker seeds.
 *  2. cell: a pyramid of HIDDEN flags over the grid (level l: blocks of 2^l voxels a side; a flag
 *     hides the whole block). The seeds are taken front to back (distance from the cell's box).
 *     A seed already hidden is skipped (paper: occluded blockers are not used). Otherwise it is
 *     EXTENDED, one layer of voxels at a time in each of the six directions in turn, while the
 *     layer is opaque or already hidden (the paper's extension into hidden space: occluder fusion).
 *     The shaft of the extended box B (shrunk by `margin`) from the cell is its umbra U: the points
 *     P such that every segment from a point of the cell to P meets B. U is convex, the
 *     intersection over the cell's vertices v of the shadow of B from v (the half-spaces of the
 *     silhouette planes through v and of B's faces turned towards v), so a block of voxels is
 *     inside U when its eight corners are, and outside when all of them are outside one of those
 *     planes. Blocks inside U are flagged hidden, coarsest first.
 *  3. An object is in the set unless every voxel its box meets is hidden (or its box leaves the
 *     grid). On a Quake III map the objects no BSP leaf lists (brush models: doors, platforms,
 *     which move) are in every set, as with `portal`.
 *
 * Why conservative. HIDDEN(P): every segment from the cell to P passes through the interior of
 * solid matter. Opaque voxels are solid. If P is in U, the segment vP (v in the cell) passes
 * through the interior of B, hence through the interior of a voxel of B that is opaque (blocked)
 * or hidden, at a point Q whose segment vQ, a part of vP, is blocked by induction (the voxels were
 * flagged earlier). For a fixed P the set of v whose segment meets the convex B is convex, so a
 * P whose segments from the cell's vertices meet B has every segment from the cell meeting B:
 * testing the vertices suffices, and U is convex. Blocks are flagged only with every corner
 * `tol` inside every plane. Leaving a seed out, not extending it or not flagging a block can only
 * keep more objects. A cell whose vertex lies on B's boundary (within margin) does not use B.
 * For CLUSTER cells the cell is the box of its leaves, which holds every eye of the cluster.
 * Objects are judged by their boxes; detail geometry that is not solid (open meshes, trees,
 * cars) is never an occluder. */
#include "pvs_internal.h"

#include <math.h>
#include <stdlib.h>

#define VOL_LEVELS 12      /* pyramid levels at most (blocks of 2048 voxels a side) */
#define VOL_MAXPLANES 128  /* umbra planes: <= 8 cell vertices x (6 silhouette + 3 face planes) */
#define VOL_TOL 1e-4       /* a block is inside the umbra when its corners are this far inside */

typedef struct vol_config {
    float voxel;          /* voxel side in metres; 0: the smallest with at most max_voxels voxels */
    uint32_t max_voxels;  /* millions */
    float margin;         /* blockers shrink by this much (metres) before their umbra is built */
    bool extend;          /* grow blockers into opaque and hidden voxels (occluder fusion) */
    bool extend_away;     /* into hidden voxels also in the directions pointing away from the cell */
    bool meshes;          /* closed meshes as solids (besides footprints and BSP solid space) */
} vol_config;

typedef struct vol_box { uint16_t lo[3], hi[3]; } vol_box; /* voxel ranges, hi exclusive */
typedef struct vol_ord { double key; uint32_t id; } vol_ord;

typedef struct vol_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    vol_config cfg;
    double org[3], side;
    uint32_t n[3];
    size_t nvox;
    uint8_t *solid;       /* nvox: 1 when the voxel is entirely inside solid matter */
    vol_box *seeds;
    uint32_t nseeds;
    uint32_t levels;
    uint32_t ln[VOL_LEVELS][3]; /* dims per level */
    size_t loff[VOL_LEVELS + 1];
    uint32_t nobj;
    uint8_t *always;      /* nobj, or NULL: objects in every set (brush models of a BSP) */
} vol_shared;

typedef struct vol_worker {
    vol_shared *sh;
    uint8_t *hidden;      /* all levels, loff offsets */
    vol_ord *ord;  /* nseeds: the seeds by distance from the cell */
} vol_worker;

/* ---- grid helpers ---- */

static inline size_t vidx(const uint32_t n[3], uint32_t i, uint32_t j, uint32_t k)
{
    return ((size_t)k * n[1] + j) * n[0] + i;
}

static inline bool hidden_at(const vol_worker *w, uint32_t i, uint32_t j, uint32_t k)
{
    const vol_shared *s = w->sh;
    /* top down: hidden voxels are mostly hidden by a coarse block */
    for (uint32_t l = s->levels; l-- > 0;)
        if (w->hidden[s->loff[l] + vidx(s->ln[l], i >> l, j >> l, k >> l)])
            return true;
    return false;
}

/* Whether every voxel of [lo, hi) is hidden (node (l, i, j, k) and below). */
static bool range_hidden_node(const vol_worker *w, uint32_t l, uint32_t i, uint32_t j, uint32_t k,
                              const uint32_t lo[3], const uint32_t hi[3])
{
    const vol_shared *s = w->sh;
    uint32_t c[3] = {i, j, k};
    for (int a = 0; a < 3; a++) {
        uint64_t b0 = (uint64_t)c[a] << l, b1 = (uint64_t)(c[a] + 1) << l;
        if (b1 <= lo[a] || b0 >= hi[a])
            return true; /* no voxel of the range here */
    }
    if (w->hidden[s->loff[l] + vidx(s->ln[l], i, j, k)])
        return true;
    if (l == 0)
        return false;
    uint32_t m = l - 1;
    for (uint32_t dk = 0; dk < 2; dk++)
        for (uint32_t dj = 0; dj < 2; dj++)
            for (uint32_t di = 0; di < 2; di++) {
                uint32_t ci = 2 * i + di, cj = 2 * j + dj, ck = 2 * k + dk;
                if (ci >= s->ln[m][0] || cj >= s->ln[m][1] || ck >= s->ln[m][2])
                    continue;
                if (!range_hidden_node(w, m, ci, cj, ck, lo, hi))
                    return false;
            }
    return true;
}

static bool range_hidden(const vol_worker *w, const uint32_t lo[3], const uint32_t hi[3])
{
    return range_hidden_node(w, w->sh->levels - 1, 0, 0, 0, lo, hi);
}

/* ---- umbra planes ---- */

typedef struct vol_planes { double p[VOL_MAXPLANES][4]; int n; } vol_planes;

static bool plane_add(vol_planes *u, const double nrm[3], const double at[3], const double inside[3])
{
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (!(len > 1e-12) || u->n >= VOL_MAXPLANES)
        return false; /* a plane left out would enlarge the umbra: the caller drops the blocker */
    double p[4] = {nrm[0] / len, nrm[1] / len, nrm[2] / len, 0};
    p[3] = -(p[0] * at[0] + p[1] * at[1] + p[2] * at[2]);
    /* orient: the point `inside` (inside B) on the negative side */
    if (p[0] * inside[0] + p[1] * inside[1] + p[2] * inside[2] + p[3] > 0)
        for (int c = 0; c < 4; c++)
            p[c] = -p[c];
    for (int q = 0; q < u->n; q++)
        if (memcmp(u->p[q], p, sizeof p) == 0)
            return true; /* the same face plane from another vertex */
    memcpy(u->p[u->n++], p, sizeof p);
    return true;
}

/* The planes of the umbra of box [lo, hi] from the convex hull of the cell's vertices. A face
 * plane within 1e-5 of a vertex is first moved 2e-5 into the box (a smaller blocker hides less:
 * conservative), so that no vertex lies on a face plane or an edge line; false when the box
 * vanishes or a plane cannot be built (the blocker is then not used). A vertex inside the box adds
 * no plane (every segment from it meets the box). */
static bool umbra_planes(double lo[3], double hi[3], const double (*cv)[3], int ncv, vol_planes *u)
{
    u->n = 0;
    for (int it = 0; it < 8; it++) {
        bool moved = false;
        for (int q = 0; q < ncv; q++)
            for (int a = 0; a < 3; a++) {
                if (fabs(cv[q][a] - lo[a]) < 1e-5) {
                    lo[a] += 2e-5;
                    moved = true;
                }
                if (fabs(cv[q][a] - hi[a]) < 1e-5) {
                    hi[a] -= 2e-5;
                    moved = true;
                }
            }
        if (!moved)
            break;
        if (it == 7)
            return false;
    }
    for (int a = 0; a < 3; a++)
        if (!(hi[a] - lo[a] > 1e-5))
            return false;
    double ctr[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
    for (int q = 0; q < ncv; q++) {
        const double *v = cv[q];
        /* face f = 2a + s: axis a, s = 0 the lo face (outward -a), 1 the hi face */
        bool front[6];
        bool inside = true;
        for (int a = 0; a < 3; a++) {
            front[2 * a] = lo[a] - v[a] > 0;
            front[2 * a + 1] = v[a] - hi[a] > 0;
            if (front[2 * a] || front[2 * a + 1])
                inside = false;
        }
        if (inside)
            continue;
        /* front faces: beyond them */
        for (int a = 0; a < 3; a++)
            for (int sd = 0; sd < 2; sd++)
                if (front[2 * a + sd]) {
                    double nrm[3] = {0, 0, 0}, at[3] = {ctr[0], ctr[1], ctr[2]};
                    nrm[a] = sd ? 1 : -1;
                    at[a] = sd ? hi[a] : lo[a];
                    /* the half-space on the box's side of the face */
                    if (!plane_add(u, nrm, at, ctr))
                        return false;
                }
        /* silhouette edges: edges along axis a at (b, c) = (sb, sc) between faces 2b+sb and 2c+sc */
        for (int a = 0; a < 3; a++) {
            int b = (a + 1) % 3, c = (a + 2) % 3;
            for (int sb = 0; sb < 2; sb++)
                for (int sc = 0; sc < 2; sc++) {
                    if (front[2 * b + sb] == front[2 * c + sc])
                        continue;
                    double e0[3], e1[3];
                    e0[a] = lo[a];
                    e1[a] = hi[a];
                    e0[b] = e1[b] = sb ? hi[b] : lo[b];
                    e0[c] = e1[c] = sc ? hi[c] : lo[c];
                    double d[3] = {e1[0] - e0[0], e1[1] - e0[1], e1[2] - e0[2]};
                    double w[3] = {v[0] - e0[0], v[1] - e0[1], v[2] - e0[2]};
                    double nrm[3] = {d[1] * w[2] - d[2] * w[1], d[2] * w[0] - d[0] * w[2], d[0] * w[1] - d[1] * w[0]};
                    if (!plane_add(u, nrm, e0, ctr))
                        return false;
                }
        }
    }
    return true;
}

/* Flag the blocks of node (l, i, j, k) that lie inside the umbra. `active` holds the planes the
 * node is not yet known to be inside (a parent wholly inside a plane has children wholly inside
 * it). Returns whether the node is hidden afterwards (so that a parent whose children all are is
 * flagged too). */
static bool mark_node(vol_worker *w, const vol_planes *u, const uint64_t active[2], uint32_t l, uint32_t i,
                      uint32_t j, uint32_t k, uint64_t *work)
{
    vol_shared *s = w->sh;
    uint8_t *flag = &w->hidden[s->loff[l] + vidx(s->ln[l], i, j, k)];
    if (*flag)
        return true;
    (*work)++;
    double lo[3], hi[3];
    uint32_t c[3] = {i, j, k};
    for (int a = 0; a < 3; a++) {
        uint64_t b0 = (uint64_t)c[a] << l, b1 = (uint64_t)(c[a] + 1) << l;
        if (b1 > s->n[a])
            b1 = s->n[a];
        lo[a] = s->org[a] + (double)b0 * s->side;
        hi[a] = s->org[a] + (double)b1 * s->side;
    }
    double ctr[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
    double hx[3] = {(hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, (hi[2] - lo[2]) / 2};
    uint64_t still[2] = {0, 0};
    for (int wd = 0; wd < 2; wd++)
        for (uint64_t m = active[wd]; m; m &= m - 1) {
            int q = 64 * wd + __builtin_ctzll(m);
            const double *p = u->p[q];
            double val = p[0] * ctr[0] + p[1] * ctr[1] + p[2] * ctr[2] + p[3];
            double r = fabs(p[0]) * hx[0] + fabs(p[1]) * hx[1] + fabs(p[2]) * hx[2];
            if (val - r > 0)
                return false; /* wholly outside this plane: nothing here is in the umbra */
            if (val + r > -VOL_TOL)
                still[wd] |= m & -m;
        }
    if (!still[0] && !still[1]) {
        *flag = 1;
        return true;
    }
    if (l == 0)
        return false;
    uint32_t mm = l - 1;
    bool all = true;
    for (uint32_t dk = 0; dk < 2; dk++)
        for (uint32_t dj = 0; dj < 2; dj++)
            for (uint32_t di = 0; di < 2; di++) {
                uint32_t ci = 2 * i + di, cj = 2 * j + dj, ck = 2 * k + dk;
                if (ci >= s->ln[mm][0] || cj >= s->ln[mm][1] || ck >= s->ln[mm][2])
                    continue;
                if (!mark_node(w, u, still, mm, ci, cj, ck, work))
                    all = false;
            }
    if (all)
        *flag = 1;
    return all;
}

/* ---- blocker extension ---- */

/* Whether every voxel of the layer [lo, hi) is opaque, or (with `hidden`) opaque or hidden. */
static bool layer_blocks(const vol_worker *w, const uint32_t lo[3], const uint32_t hi[3], bool hidden)
{
    const vol_shared *s = w->sh;
    if (hidden && range_hidden(w, lo, hi))
        return true;
    for (uint32_t k = lo[2]; k < hi[2]; k++)
        for (uint32_t j = lo[1]; j < hi[1]; j++)
            for (uint32_t i = lo[0]; i < hi[0]; i++)
                if (!s->solid[vidx(s->n, i, j, k)] && (!hidden || !hidden_at(w, i, j, k)))
                    return false;
    return true;
}

/* Grow [lo, hi) one layer at a time in the six directions in turn while the layer is opaque or
 * hidden. */
static void extend(const vol_worker *w, uint32_t lo[3], uint32_t hi[3], const double cb_lo[3], const double cb_hi[3])
{
    const vol_shared *s = w->sh;
    /* directions pointing away from the cell (the cell wholly on the other side) grow through
     * opaque voxels only unless `away`: the deep hidden space behind adds little and costs most */
    bool away[6];
    for (int a = 0; a < 3; a++) {
        away[2 * a] = cb_lo[a] >= s->org[a] + hi[a] * s->side;
        away[2 * a + 1] = cb_hi[a] <= s->org[a] + lo[a] * s->side;
    }
    bool grew = true;
    while (grew) {
        grew = false;
        for (int f = 0; f < 6; f++) {
            int a = f >> 1;

            uint32_t llo[3] = {lo[0], lo[1], lo[2]}, lhi[3] = {hi[0], hi[1], hi[2]};
            if (f & 1) {
                if (hi[a] >= s->n[a])
                    continue;
                llo[a] = hi[a];
                lhi[a] = hi[a] + 1;
            } else {
                if (lo[a] == 0)
                    continue;
                llo[a] = lo[a] - 1;
                lhi[a] = lo[a];
            }
            if (layer_blocks(w, llo, lhi, !away[f] || s->cfg.extend_away)) {
                if (f & 1)
                    hi[a]++;
                else
                    lo[a]--;
                grew = true;
            }
        }
    }
}

/* ---- preparation: solid voxels ---- */

static bool point_in_polygon(const float *xy, uint32_t n, double x, double y)
{
    bool in = false;
    for (uint32_t i = 0, j = n - 1; i < n; j = i++) {
        double xi = xy[2 * i], yi = xy[2 * i + 1], xj = xy[2 * j], yj = xy[2 * j + 1];
        if ((yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi)
            in = !in;
    }
    return in;
}

/* Whether segment ab meets the closed rectangle [x0, x1] x [y0, y1] (Liang-Barsky). */
static bool segment_meets_rect(double ax, double ay, double bx, double by, double x0, double y0, double x1,
                               double y1)
{
    double t0 = 0, t1 = 1, d[2] = {bx - ax, by - ay}, p0[2] = {ax, ay}, lo[2] = {x0, y0}, hi[2] = {x1, y1};
    for (int a = 0; a < 2; a++) {
        if (fabs(d[a]) < 1e-300) {
            if (p0[a] < lo[a] || p0[a] > hi[a])
                return false;
            continue;
        }
        double ta = (lo[a] - p0[a]) / d[a], tb = (hi[a] - p0[a]) / d[a];
        if (ta > tb) {
            double t = ta;
            ta = tb;
            tb = t;
        }
        if (ta > t0)
            t0 = ta;
        if (tb < t1)
            t1 = tb;
        if (t0 > t1)
            return false;
    }
    return true;
}

static void range_of(const vol_shared *s, int a, double lo, double hi, uint32_t *r0, uint32_t *r1)
{
    double f0 = (lo - s->org[a]) / s->side, f1 = (hi - s->org[a]) / s->side;
    double c0 = floor(f0), c1 = ceil(f1);
    if (c0 < 0)
        c0 = 0;
    if (c1 > s->n[a])
        c1 = s->n[a];
    if (c1 < c0)
        c1 = c0;
    *r0 = (uint32_t)c0;
    *r1 = (uint32_t)c1;
}

static void solid_footprints(vol_shared *s)
{
    uint32_t nf = sl_scene_footprint_count(s->scene);
    const double m = 1e-4; /* a square must clear every edge by this much */
    for (uint32_t f = 0; f < nf; f++) {
        sl_footprint_view fp = sl_scene_footprint(s->scene, f);
        if (fp.vertex_count < 3)
            continue;
        double bx0 = INFINITY, by0 = INFINITY, bx1 = -INFINITY, by1 = -INFINITY;
        for (uint32_t v = 0; v < fp.vertex_count; v++) {
            bx0 = fmin(bx0, fp.xy[2 * v]);
            bx1 = fmax(bx1, fp.xy[2 * v]);
            by0 = fmin(by0, fp.xy[2 * v + 1]);
            by1 = fmax(by1, fp.xy[2 * v + 1]);
        }
        uint32_t i0, i1, j0, j1, k0, k1;
        range_of(s, 0, bx0, bx1, &i0, &i1);
        range_of(s, 1, by0, by1, &j0, &j1);
        /* voxels wholly inside [base, roof] */
        double z0 = ceil(((double)fp.base_z - s->org[2]) / s->side), z1 = floor(((double)fp.roof_z - s->org[2]) / s->side);
        if (z0 < 0)
            z0 = 0;
        if (z1 > s->n[2])
            z1 = s->n[2];
        if (z1 <= z0)
            continue;
        k0 = (uint32_t)z0;
        k1 = (uint32_t)z1;
        /* exact: a voxel boundary on base or roof is inside; ceil/floor on rounding can only
         * drop a layer */
        while (k0 < k1 && s->org[2] + (double)k0 * s->side < fp.base_z)
            k0++;
        while (k1 > k0 && s->org[2] + (double)k1 * s->side > fp.roof_z)
            k1--;
        for (uint32_t j = j0; j < j1; j++)
            for (uint32_t i = i0; i < i1; i++) {
                double x0 = s->org[0] + i * s->side, x1 = x0 + s->side, y0 = s->org[1] + j * s->side, y1 = y0 + s->side;
                bool in = point_in_polygon(fp.xy, fp.vertex_count, x0, y0) &&
                          point_in_polygon(fp.xy, fp.vertex_count, x1, y0) &&
                          point_in_polygon(fp.xy, fp.vertex_count, x0, y1) &&
                          point_in_polygon(fp.xy, fp.vertex_count, x1, y1);
                for (uint32_t e = 0; in && e < fp.vertex_count; e++) {
                    uint32_t e1 = (e + 1) % fp.vertex_count;
                    if (segment_meets_rect(fp.xy[2 * e], fp.xy[2 * e + 1], fp.xy[2 * e1], fp.xy[2 * e1 + 1], x0 - m,
                                           y0 - m, x1 + m, y1 + m))
                        in = false;
                }
                if (in)
                    for (uint32_t k = k0; k < k1; k++)
                        s->solid[vidx(s->n, i, j, k)] = 1;
            }
    }
}

/* BSP: 0 the box meets only open leaves, 1 only solid leaves (no cluster), 2 both. */
static int bsp_classify(const sl_bsp_view *bv, const double (*planes)[4], int32_t child, const double lo[3],
                        const double hi[3])
{
    if (child < 0) {
        uint32_t leaf = (uint32_t)(-(child + 1));
        return leaf < bv->leaf_count && bv->leaves[leaf].cluster >= 0 ? 0 : 1;
    }
    const sl_bsp_node *nd = &bv->nodes[child];
    const double *p = planes[nd->plane];
    double ctr[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
    double val = p[0] * ctr[0] + p[1] * ctr[1] + p[2] * ctr[2] + p[3];
    double r = fabs(p[0]) * (hi[0] - lo[0]) / 2 + fabs(p[1]) * (hi[1] - lo[1]) / 2 + fabs(p[2]) * (hi[2] - lo[2]) / 2;
    const double band = 1e-3;
    int res = -1;
    if (val + r >= -band) {
        res = bsp_classify(bv, planes, nd->children[0], lo, hi);
        if (res == 2)
            return 2;
    }
    if (val - r <= band) {
        int b = bsp_classify(bv, planes, nd->children[1], lo, hi);
        res = res < 0 ? b : (res == b ? res : 2);
    }
    return res < 0 ? 1 : res;
}

static void solid_bsp_range(vol_shared *s, const sl_bsp_view *bv, const double (*planes)[4], const uint32_t lo[3],
                            const uint32_t hi[3])
{
    double blo[3], bhi[3];
    for (int a = 0; a < 3; a++) {
        blo[a] = s->org[a] + lo[a] * s->side;
        bhi[a] = s->org[a] + hi[a] * s->side;
    }
    int c = bsp_classify(bv, planes, 0, blo, bhi);
    if (c == 0)
        return;
    if (c == 1) {
        for (uint32_t k = lo[2]; k < hi[2]; k++)
            for (uint32_t j = lo[1]; j < hi[1]; j++)
                memset(&s->solid[vidx(s->n, lo[0], j, k)], 1, hi[0] - lo[0]);
        return;
    }
    int a = 0;
    for (int b = 1; b < 3; b++)
        if (hi[b] - lo[b] > hi[a] - lo[a])
            a = b;
    if (hi[a] - lo[a] <= 1)
        return; /* one mixed voxel: not solid */
    uint32_t mid = lo[a] + (hi[a] - lo[a]) / 2;
    uint32_t h1[3] = {hi[0], hi[1], hi[2]}, l2[3] = {lo[0], lo[1], lo[2]};
    h1[a] = mid;
    l2[a] = mid;
    solid_bsp_range(s, bv, planes, lo, h1);
    solid_bsp_range(s, bv, planes, l2, hi);
}

static sl_status solid_bsp(vol_shared *s, sl_error *err)
{
    sl_bsp_view bv;
    if (!sl_scene_bsp(s->scene, &bv) || bv.node_count == 0)
        return SL_OK;
    double(*planes)[4] = sl_alloc(&s->a, (size_t)(bv.plane_count ? bv.plane_count : 1) * sizeof *planes);
    if (!planes)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    for (uint32_t i = 0; i < bv.plane_count; i++) {
        const sl_plane *p = &bv.planes[i];
        double len = sqrt((double)p->a * p->a + (double)p->b * p->b + (double)p->c * p->c);
        if (!(len > 0) || !isfinite(len) || !isfinite(p->d)) {
            sl_free(&s->a, planes, (size_t)(bv.plane_count ? bv.plane_count : 1) * sizeof *planes);
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "volumetric: BSP plane %u has no valid normal", i);
        }
        planes[i][0] = p->a / len;
        planes[i][1] = p->b / len;
        planes[i][2] = p->c / len;
        planes[i][3] = p->d / len;
    }
    uint32_t lo[3] = {0, 0, 0};
    solid_bsp_range(s, &bv, (const double(*)[4])planes, lo, s->n);
    sl_free(&s->a, planes, (size_t)(bv.plane_count ? bv.plane_count : 1) * sizeof *planes);
    return SL_OK;
}

typedef struct vol_edge { uint32_t a, b; } vol_edge;
typedef struct vol_pv { float p[3]; uint32_t i; } vol_pv;

static void und(const vol_edge *e, uint32_t *lo, uint32_t *hi)
{
    *lo = e->a < e->b ? e->a : e->b;
    *hi = e->a < e->b ? e->b : e->a;
}

static int cmp_edge(const void *x, const void *y)
{
    const vol_edge *p = x, *q = y;
    uint32_t pa, pb, qa, qb;
    und(p, &pa, &pb);
    und(q, &qa, &qb);
    if (pa != qa)
        return pa < qa ? -1 : 1;
    if (pb != qb)
        return pb < qb ? -1 : 1;
    return (p->a > q->a) - (p->a < q->a);
}

static bool same_und(const vol_edge *p, const vol_edge *q)
{
    uint32_t pa, pb, qa, qb;
    und(p, &pa, &pb);
    und(q, &qa, &qb);
    return pa == qa && pb == qb;
}

static int cmp_pv(const void *x, const void *y)
{
    const vol_pv *p = x, *q = y;
    for (int c = 0; c < 3; c++)
        if (p->p[c] != q->p[c])
            return p->p[c] < q->p[c] ? -1 : 1;
    return (p->i > q->i) - (p->i < q->i);
}

/* Closed and consistently oriented: after welding vertices at equal positions, every undirected
 * edge of a non-degenerate triangle is used exactly twice, once each way. */
static sl_status mesh_closed(const sl_allocator *a, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt,
                             bool *closed, sl_error *err)
{
    *closed = false;
    if (nt < 4 || nv < 4)
        return SL_OK;
    uint32_t *canon = sl_alloc(a, (size_t)nv * sizeof *canon);
    vol_edge *e = sl_alloc(a, (size_t)nt * 3 * sizeof *e);
    vol_pv *tmp = sl_alloc(a, (size_t)nv * sizeof *tmp);
    sl_status st = SL_OK;
    if (!canon || !e || !tmp)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    if (st == SL_OK) {
        for (uint32_t v = 0; v < nv; v++) {
            memcpy(tmp[v].p, pos + 3 * (size_t)v, sizeof tmp[v].p);
            tmp[v].i = v;
        }
        qsort(tmp, nv, sizeof *tmp, cmp_pv);
        for (uint32_t v = 0; v < nv; v++)
            canon[tmp[v].i] = v > 0 && memcmp(tmp[v].p, tmp[v - 1].p, sizeof tmp[v].p) == 0 ? canon[tmp[v - 1].i]
                                                                                             : tmp[v].i;
        size_t ne = 0;
        for (uint32_t t = 0; t < nt; t++) {
            uint32_t v[3];
            for (int c = 0; c < 3; c++)
                v[c] = canon[idx[3 * (size_t)t + (size_t)c]];
            if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])
                continue;
            for (int c = 0; c < 3; c++)
                e[ne++] = (vol_edge){v[c], v[(c + 1) % 3]};
        }
        qsort(e, ne, sizeof *e, cmp_edge);
        bool ok = ne >= 6 && ne % 2 == 0;
        for (size_t i = 0; ok && i < ne; i += 2)
            if (!(e[i].a == e[i + 1].b && e[i].b == e[i + 1].a) || (i + 2 < ne && same_und(&e[i + 1], &e[i + 2])))
                ok = false;
        *closed = ok;
    }
    sl_free(a, canon, (size_t)nv * sizeof *canon);
    sl_free(a, e, (size_t)nt * 3 * sizeof *e);
    sl_free(a, tmp, (size_t)nv * sizeof *tmp);
    return st;
}

/* One closed mesh in world space: sl_shrink_mesh_voxels (eps 0) gives the voxels of its own grid
 * that lie wholly inside (corners inside by ray parity, no triangle crossing); a voxel of ours is
 * solid when those disjoint boxes fill it (their volumes inside it add up to its volume, to 1e-6
 * of it). */
static sl_status solid_mesh(vol_shared *s, sl_mesh_view mv, const sl_affine *xf, double *cover, sl_error *err)
{
    const sl_allocator *a = &s->a;
    float *pos = sl_alloc(a, (size_t)mv.vertex_count * 3 * sizeof *pos);
    if (!pos)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    for (uint32_t v = 0; v < mv.vertex_count; v++) {
        sl_vec3 p = {mv.positions[3 * (size_t)v], mv.positions[3 * (size_t)v + 1], mv.positions[3 * (size_t)v + 2]};
        if (xf)
            p = sl_affine_point(xf, p);
        pos[3 * (size_t)v] = p.x;
        pos[3 * (size_t)v + 1] = p.y;
        pos[3 * (size_t)v + 2] = p.z;
    }
    bool closed;
    sl_status st = mesh_closed(a, pos, mv.vertex_count, mv.indices, mv.triangle_count, &closed, err);
    sl_aabb *boxes = NULL;
    uint32_t nb = 0;
    if (st == SL_OK && closed) {
        /* only meshes large enough to hold a whole voxel */
        float ex = fminf(fminf(mv.bounds.max.x - mv.bounds.min.x, mv.bounds.max.y - mv.bounds.min.y),
                         mv.bounds.max.z - mv.bounds.min.z);
        if (xf || ex >= (float)s->side) {
            /* a quarter of our side (half where that grid would be too large): its voxels lie
             * on the mesh's bounds, ours need not, so ours are covered a finer voxel inside */
            st = sl_shrink_mesh_voxels(pos, mv.vertex_count, mv.indices, mv.triangle_count, (float)(s->side / 4), 0,
                                       a, &boxes, &nb, err);
            if (st == SL_ERROR_LIMIT)
                st = sl_shrink_mesh_voxels(pos, mv.vertex_count, mv.indices, mv.triangle_count,
                                           (float)(s->side / 2), 0, a, &boxes, &nb, err);
            if (st == SL_ERROR_LIMIT) { /* still too fine for that mesh: it is not used (conservative) */
                st = SL_OK;
                boxes = NULL;
                nb = 0;
            }
        }
    }
    sl_free(a, pos, (size_t)mv.vertex_count * 3 * sizeof *pos);
    if (st != SL_OK)
        return st;
    double vol = s->side * s->side * s->side;
    uint32_t touched_lo[3] = {UINT32_MAX, UINT32_MAX, UINT32_MAX}, touched_hi[3] = {0, 0, 0};
    for (uint32_t b = 0; b < nb; b++) {
        double lo[3] = {boxes[b].min.x, boxes[b].min.y, boxes[b].min.z};
        double hi[3] = {boxes[b].max.x, boxes[b].max.y, boxes[b].max.z};
        uint32_t r0[3], r1[3];
        for (int c = 0; c < 3; c++) {
            range_of(s, c, lo[c], hi[c], &r0[c], &r1[c]);
            if (r0[c] < touched_lo[c])
                touched_lo[c] = r0[c];
            if (r1[c] > touched_hi[c])
                touched_hi[c] = r1[c];
        }
        for (uint32_t k = r0[2]; k < r1[2]; k++)
            for (uint32_t j = r0[1]; j < r1[1]; j++)
                for (uint32_t i = r0[0]; i < r1[0]; i++) {
                    uint32_t c3[3] = {i, j, k};
                    double ov = 1;
                    for (int c = 0; c < 3; c++) {
                        double v0 = s->org[c] + c3[c] * s->side, v1 = v0 + s->side;
                        double o = fmin(v1, hi[c]) - fmax(v0, lo[c]);
                        ov *= o > 0 ? o : 0;
                    }
                    cover[vidx(s->n, i, j, k)] += ov;
                }
    }
    if (boxes)
        sl_shrink_boxes_free(a, boxes, nb);
    if (nb == 0)
        return SL_OK;
    for (uint32_t k = touched_lo[2]; k < touched_hi[2]; k++)
        for (uint32_t j = touched_lo[1]; j < touched_hi[1]; j++)
            for (uint32_t i = touched_lo[0]; i < touched_hi[0]; i++) {
                size_t v = vidx(s->n, i, j, k);
                if (cover[v] >= vol * (1 - 1e-6))
                    s->solid[v] = 1;
                cover[v] = 0;
            }
    return SL_OK;
}

static sl_status solid_meshes(vol_shared *s, sl_error *err)
{
    uint32_t nobj = s->nobj, nf = sl_scene_footprint_count(s->scene), no = sl_scene_occluder_count(s->scene);
    uint8_t *has_fp = sl_calloc(&s->a, nobj ? nobj : 1, 1);
    double *cover = sl_calloc(&s->a, s->nvox, sizeof *cover);
    sl_status st = SL_OK;
    if (!has_fp || !cover)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory for %zu voxels", s->nvox);
    for (uint32_t f = 0; st == SL_OK && f < nf; f++) {
        sl_footprint_view fp = sl_scene_footprint(s->scene, f);
        if (fp.object < nobj)
            has_fp[fp.object] = 1;
    }
    for (uint32_t id = 0; st == SL_OK && id < nobj; id++) {
        sl_object_view ov = sl_scene_object(s->scene, id);
        if (has_fp[id] || !(ov.flags & SL_OBJECT_OCCLUDER) || (ov.flags & (SL_OBJECT_SEE_THROUGH | SL_OBJECT_DYNAMIC)))
            continue;
        st = solid_mesh(s, sl_scene_mesh(s->scene, ov.mesh), ov.identity ? NULL : &ov.transform, cover, err);
    }
    for (uint32_t o = 0; st == SL_OK && o < no; o++) {
        sl_occluder_view oc = sl_scene_occluder(s->scene, o);
        st = solid_mesh(s, sl_scene_mesh(s->scene, oc.mesh), &oc.transform, cover, err);
    }
    sl_free(&s->a, has_fp, nobj ? nobj : 1);
    sl_free(&s->a, cover, s->nvox * sizeof *cover);
    return st;
}

/* The opaque voxels as boxes: greedy, a run along x, widened along y, then z. */
static sl_status make_seeds(vol_shared *s, sl_error *err)
{
    uint8_t *used = sl_calloc(&s->a, s->nvox, 1);
    size_t cap = 0;
    if (!used)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    const uint32_t *n = s->n;
    sl_status st = SL_OK;
    for (uint32_t k = 0; k < n[2] && st == SL_OK; k++)
        for (uint32_t j = 0; j < n[1] && st == SL_OK; j++)
            for (uint32_t i = 0; i < n[0] && st == SL_OK; i++) {
                size_t v = vidx(n, i, j, k);
                if (!s->solid[v] || used[v])
                    continue;
                uint32_t i1 = i + 1, j1 = j + 1, k1 = k + 1;
                while (i1 < n[0] && s->solid[vidx(n, i1, j, k)] && !used[vidx(n, i1, j, k)])
                    i1++;
                for (bool ok = true; ok && j1 < n[1];) {
                    for (uint32_t x = i; x < i1 && ok; x++)
                        ok = s->solid[vidx(n, x, j1, k)] && !used[vidx(n, x, j1, k)];
                    if (ok)
                        j1++;
                }
                for (bool ok = true; ok && k1 < n[2];) {
                    for (uint32_t y = j; y < j1 && ok; y++)
                        for (uint32_t x = i; x < i1 && ok; x++)
                            ok = s->solid[vidx(n, x, y, k1)] && !used[vidx(n, x, y, k1)];
                    if (ok)
                        k1++;
                }
                for (uint32_t z = k; z < k1; z++)
                    for (uint32_t y = j; y < j1; y++)
                        memset(&used[vidx(n, i, y, z)], 1, i1 - i);
                if (s->nseeds + 1 > cap) {
                    size_t nc = cap ? 2 * cap : 1024;
                    vol_box *nb = sl_alloc(&s->a, nc * sizeof *nb);
                    if (!nb) {
                        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
                        break;
                    }
                    if (s->seeds) {
                        memcpy(nb, s->seeds, s->nseeds * sizeof *nb);
                        sl_free(&s->a, s->seeds, cap * sizeof *nb);
                    }
                    s->seeds = nb;
                    cap = nc;
                }
                s->seeds[s->nseeds++] = (vol_box){{(uint16_t)i, (uint16_t)j, (uint16_t)k},
                                                  {(uint16_t)i1, (uint16_t)j1, (uint16_t)k1}};
            }
    sl_free(&s->a, used, s->nvox);
    /* shrink the array to its size for the release */
    if (st == SL_OK && s->seeds && cap != s->nseeds) {
        vol_box *nb = sl_alloc(&s->a, (s->nseeds ? s->nseeds : 1) * sizeof *nb);
        if (!nb)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
        memcpy(nb, s->seeds, s->nseeds * sizeof *nb);
        sl_free(&s->a, s->seeds, cap * sizeof *nb);
        s->seeds = nb;
    } else if (st != SL_OK && s->seeds) {
        sl_free(&s->a, s->seeds, cap * sizeof *s->seeds);
        s->seeds = NULL;
        s->nseeds = 0;
    }
    return st;
}

/* ---- method ---- */

static sl_status vol_configure(sl_opts *o, void *config, sl_error *err)
{
    vol_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "voxel", 0, 0, 1000, &c->voxel, err)) != SL_OK ||
        (st = sl_opts_u32(o, "max_voxels", 8, 1, 512, &c->max_voxels, err)) != SL_OK ||
        (st = sl_opts_float(o, "margin", 0.001f, 1e-5f, 1, &c->margin, err)) != SL_OK ||
        (st = sl_opts_bool(o, "extend", true, &c->extend, err)) != SL_OK ||
        (st = sl_opts_bool(o, "away", true, &c->extend_away, err)) != SL_OK ||
        (st = sl_opts_bool(o, "meshes", true, &c->meshes, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void vol_release(void *p)
{
    vol_shared *s = p;
    if (!s)
        return;
    sl_allocator a = s->a;
    sl_free(&a, s->solid, s->nvox);
    if (s->always)
        sl_free(&a, s->always, s->nobj ? s->nobj : 1);
    sl_free(&a, s->seeds, (s->nseeds ? s->nseeds : 1) * sizeof *s->seeds);
    sl_free(&a, s, sizeof *s);
}

static int cmp_float(const void *x, const void *y)
{
    float p = *(const float *)x, q = *(const float *)y;
    return (p > q) - (p < q);
}

static sl_status vol_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                             uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads;
    *removed = 0;
    const vol_config *cfg = config;
    sl_aabb b = sl_scene_bounds(scene);
    /* the cells too: objects are judged inside the grid only */
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++) {
        b.min.x = fminf(b.min.x, vc[i].bounds.min.x);
        b.min.y = fminf(b.min.y, vc[i].bounds.min.y);
        b.min.z = fminf(b.min.z, vc[i].bounds.min.z);
        b.max.x = fmaxf(b.max.x, vc[i].bounds.max.x);
        b.max.y = fmaxf(b.max.y, vc[i].bounds.max.y);
        b.max.z = fmaxf(b.max.z, vc[i].bounds.max.z);
    }
    double ext[3] = {(double)b.max.x - b.min.x, (double)b.max.y - b.min.y, (double)b.max.z - b.min.z};
    if (!(ext[0] >= 0 && ext[1] >= 0 && ext[2] >= 0) || !isfinite(ext[0] + ext[1] + ext[2]))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "volumetric: the scene has no finite bounds");
    double budget = (double)cfg->max_voxels * 1e6;
    double side = cfg->voxel;
    if (side <= 0) {
        side = cbrt((ext[0] + 1e-3) * (ext[1] + 1e-3) * (ext[2] + 1e-3) / budget);
        for (int it = 0; it < 64; it++) {
            double cnt = ceil(ext[0] / side + 2) * ceil(ext[1] / side + 2) * ceil(ext[2] / side + 2);
            if (cnt <= budget)
                break;
            side *= 1.02;
        }
        side = fmax(side, 1e-3);
    }
    double cnt = ceil(ext[0] / side + 2) * ceil(ext[1] / side + 2) * ceil(ext[2] / side + 2);
    if (cnt > budget || ceil(ext[0] / side + 2) > 65535 || ceil(ext[1] / side + 2) > 65535 ||
        ceil(ext[2] / side + 2) > 65535)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "volumetric: voxel=%g gives %.0f voxels, over max_voxels=%u million (or 65535 a side): "
                       "give a larger voxel or max_voxels",
                       side, cnt, cfg->max_voxels);
    vol_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->cfg = *cfg;
    s->side = side;
    s->nobj = sl_scene_object_count(scene);
    double lo[3] = {b.min.x, b.min.y, b.min.z};
    for (int a = 0; a < 3; a++) {
        s->n[a] = (uint32_t)ceil(ext[a] / side + 2);
        s->org[a] = lo[a] - side; /* one voxel of margin each side */
    }
    /* a city: put a voxel boundary on the ground the buildings stand on (their median base), so
     * that the lowest layer of a building is solid and blocks sight lines down to the ground */
    uint32_t nf = sl_scene_footprint_count(scene);
    if (nf > 0) {
        float *bases = sl_alloc(alloc, (size_t)nf * sizeof *bases);
        if (!bases) {
            vol_release(s);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
        }
        for (uint32_t f = 0; f < nf; f++)
            bases[f] = sl_scene_footprint(scene, f).base_z;
        qsort(bases, nf, sizeof *bases, cmp_float);
        double base = bases[nf / 2];
        sl_free(alloc, bases, (size_t)nf * sizeof *bases);
        double below = ceil((base - lo[2]) / side) + 1; /* voxels from the new origin up to the base */
        s->org[2] = base - below * side;
        s->n[2] = (uint32_t)ceil(((double)b.max.z - s->org[2]) / side + 1);
    }
    if (s->n[2] > 65535) {
        vol_release(s);
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "volumetric: voxel=%g gives %u voxels in z (65535 at most)",
                       side, s->n[2]);
    }
    s->nvox = (size_t)s->n[0] * s->n[1] * s->n[2];
    uint32_t d[3] = {s->n[0], s->n[1], s->n[2]};
    s->levels = 0;
    s->loff[0] = 0;
    for (;;) {
        memcpy(s->ln[s->levels], d, sizeof d);
        s->loff[s->levels + 1] = s->loff[s->levels] + (size_t)d[0] * d[1] * d[2];
        s->levels++;
        if ((d[0] == 1 && d[1] == 1 && d[2] == 1) || s->levels == VOL_LEVELS)
            break;
        for (int a = 0; a < 3; a++)
            d[a] = (d[a] + 1) / 2;
    }
    if (d[0] != 1 || d[1] != 1 || d[2] != 1) {
        vol_release(s);
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "volumetric: grid too large for %d levels", VOL_LEVELS);
    }
    s->solid = sl_calloc(alloc, s->nvox, 1);
    if (!s->solid) {
        vol_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory for %zu voxels", s->nvox);
    }
    solid_footprints(s);
    sl_status st = solid_bsp(s, err);
    if (st == SL_OK && cfg->meshes)
        st = solid_meshes(s, err);
    /* a Quake III map: the objects no leaf lists are its brush models (doors, platforms), which
     * move; like `portal`, keep them in every set */
    sl_bsp_view bv;
    if (st == SL_OK && sl_scene_bsp(scene, &bv) && bv.node_count > 0) {
        s->always = sl_alloc(alloc, s->nobj ? s->nobj : 1);
        if (!s->always)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
        else {
            memset(s->always, 1, s->nobj ? s->nobj : 1);
            for (uint32_t k = 0; k < bv.leaf_object_count; k++)
                if (bv.leaf_objects[k] < s->nobj)
                    s->always[bv.leaf_objects[k]] = 0;
        }
    }
    if (st == SL_OK)
        st = make_seeds(s, err);
    if (st != SL_OK) {
        vol_release(s);
        return st;
    }
    *shared = s;
    return SL_OK;
}

static void vol_worker_destroy(void *p)
{
    vol_worker *w = p;
    if (!w)
        return;
    const sl_allocator *a = &w->sh->a;
    sl_free(a, w->hidden, w->sh->loff[w->sh->levels]);
    sl_free(a, w->ord, (w->sh->nseeds ? w->sh->nseeds : 1) * sizeof *w->ord);
    sl_free(a, w, sizeof *w);
}

static sl_status vol_worker_create(void *shared, void **out, sl_error *err)
{
    vol_shared *s = shared;
    vol_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    w->sh = s;
    w->hidden = sl_alloc(&s->a, s->loff[s->levels]);
    w->ord = sl_alloc(&s->a, (s->nseeds ? s->nseeds : 1) * sizeof *w->ord);
    if (!w->hidden || !w->ord) {
        vol_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "volumetric: out of memory");
    }
    *out = w;
    return SL_OK;
}


static int cmp_ord(const void *x, const void *y)
{
    const vol_ord *p = x, *q = y;
    if (p->key != q->key)
        return p->key < q->key ? -1 : 1;
    return (p->id > q->id) - (p->id < q->id);
}

/* The cell's vertices, pushed 1 mm outwards (the eyes lie inside). */
static int cell_vertices(const sl_viewcell *c, double (*cv)[3])
{
    const double out = 1e-3;
    if (c->shape == SL_CELL_PRISM) {
        double cx = (c->tri[0].x + c->tri[1].x + c->tri[2].x) / 3.0, cy = (c->tri[0].y + c->tri[1].y + c->tri[2].y) / 3.0;
        for (int t = 0; t < 3; t++) {
            double dx = c->tri[t].x - cx, dy = c->tri[t].y - cy, len = sqrt(dx * dx + dy * dy);
            double f = len > 0 ? (len + out) / len : 1;
            for (int z = 0; z < 2; z++) {
                cv[2 * t + z][0] = cx + dx * f;
                cv[2 * t + z][1] = cy + dy * f;
                cv[2 * t + z][2] = z ? (double)c->z_max + out : (double)c->z_min - out;
            }
        }
        return 6;
    }
    for (int q = 0; q < 8; q++) {
        cv[q][0] = (q & 1) ? (double)c->bounds.max.x + out : (double)c->bounds.min.x - out;
        cv[q][1] = (q & 2) ? (double)c->bounds.max.y + out : (double)c->bounds.min.y - out;
        cv[q][2] = (q & 4) ? (double)c->bounds.max.z + out : (double)c->bounds.min.z - out;
    }
    return 8;
}

/* The set of one cell (file comment). */
static sl_status vol_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    (void)err;
    vol_worker *w = worker;
    vol_shared *s = w->sh;
    const sl_viewcell *c = &sl_viewcells_data(s->cells)[cell];
    double cv[8][3];
    int ncv = cell_vertices(c, cv);
    double cb_lo[3] = {c->bounds.min.x, c->bounds.min.y, c->bounds.min.z};
    double cb_hi[3] = {c->bounds.max.x, c->bounds.max.y, c->bounds.max.z};
    memset(w->hidden, 0, s->loff[s->levels]);
    /* front to back: distance from the cell's box to the seed's box */
    for (uint32_t q = 0; q < s->nseeds; q++) {
        const vol_box *bx = &s->seeds[q];
        double d2 = 0;
        for (int a = 0; a < 3; a++) {
            double lo = s->org[a] + bx->lo[a] * s->side, hi = s->org[a] + bx->hi[a] * s->side;
            double g = lo > cb_hi[a] ? lo - cb_hi[a] : (cb_lo[a] > hi ? cb_lo[a] - hi : 0);
            d2 += g * g;
        }
        w->ord[q] = (vol_ord){d2, q};
    }
    qsort(w->ord, s->nseeds, sizeof *w->ord, cmp_ord);
    uint64_t work = 0;
    vol_planes u;
    for (uint32_t q = 0; q < s->nseeds; q++) {
        const vol_box *bx = &s->seeds[w->ord[q].id];
        uint32_t lo[3] = {bx->lo[0], bx->lo[1], bx->lo[2]}, hi[3] = {bx->hi[0], bx->hi[1], bx->hi[2]};
        if (range_hidden(w, lo, hi))
            continue; /* an occluded blocker is not used */
        if (s->cfg.extend)
            extend(w, lo, hi, cb_lo, cb_hi);
        double blo[3], bhi[3];
        for (int a = 0; a < 3; a++) {
            blo[a] = s->org[a] + lo[a] * s->side + s->cfg.margin;
            bhi[a] = s->org[a] + hi[a] * s->side - s->cfg.margin;
        }
        if (!umbra_planes(blo, bhi, (const double(*)[3])cv, ncv, &u))
            continue;
        uint64_t all[2] = {u.n >= 64 ? ~0ull : (1ull << u.n) - 1, u.n <= 64 ? 0 : u.n >= 128 ? ~0ull : (1ull << (u.n - 64)) - 1};
        mark_node(w, &u, all, s->levels - 1, 0, 0, 0, &work);

    }
    const sl_aabb *ob = sl_scene_object_bounds_array(s->scene);
    uint32_t n = 0;
    for (uint32_t id = 0; id < s->nobj; id++) {
        double lo[3] = {ob[id].min.x, ob[id].min.y, ob[id].min.z}, hi[3] = {ob[id].max.x, ob[id].max.y, ob[id].max.z};
        bool visible = s->always && s->always[id];
        uint32_t r0[3], r1[3];
        for (int a = 0; a < 3 && !visible; a++) {
            double f0 = (lo[a] - s->org[a]) / s->side, f1 = (hi[a] - s->org[a]) / s->side;
            if (!(f0 >= 0.5) || !(f1 <= s->n[a] - 0.5) || !(f1 >= f0)) {
                visible = true; /* leaves the grid (or is no box) */
                break;
            }
            /* the voxels covering the box: a hidden voxel's umbra test holds VOL_TOL inside every
             * plane, so the points within VOL_TOL of a hidden voxel are hidden too, and a box
             * ending 1e-5 m into the next voxel needs no more */
            double d = 1e-5 / s->side;
            r0[a] = (uint32_t)floor(f0 + d);
            r1[a] = (uint32_t)ceil(f1 - d);
            if (r1[a] <= r0[a])
                r1[a] = r0[a] + 1;
        }
        if (!visible)
            visible = !range_hidden(w, r0, r1);
        if (visible)
            out->ids[n++] = id;
    }
    out->count = n;
    out->work = work;

    return SL_OK;
}

static void vol_notice(const void *config, char *buf, size_t size)
{
    (void)config;
    if (size)
        buf[0] = 0;
}

const sl_pvs_method sl_pvs_method_volumetric = {
    .name = "volumetric",
    .summary = "conservative from-region PVS on a voxelised scene (Schaufler et al. 2000): opaque voxels grown "
               "into blockers through hidden space, their shafts culled; footprints, BSP solid space, closed meshes",
    .options_help =
        "voxel=FLOAT (default 0: the smallest side keeping the grid within max_voxels): voxel side in metres\n"
        "max_voxels=INT (default 8): millions of voxels the grid may have\n"
        "margin=FLOAT (default 0.001): metres each blocker shrinks by before its shaft is built\n"
        "extend=BOOL (default true): grow blockers into opaque and hidden voxels (occluder fusion)\n"
        "away=BOOL (default true): extend into hidden voxels also in the directions pointing away from the cell "
        "(into opaque ones always)\n"
        "meshes=BOOL (default true): closed meshes of occluder objects and 3D occluders are solid too\n",
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(vol_config),
    .configure = vol_configure,
    .prepare = vol_prepare,
    .worker_create = vol_worker_create,
    .cell = vol_cell,
    .worker_destroy = vol_worker_destroy,
    .release = vol_release,
    .notice = vol_notice,
};

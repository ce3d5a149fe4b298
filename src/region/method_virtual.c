/* virtual: from-region visibility by virtual occluders, in height slices (2.5D).
 *
 * V. Koltun, Y. Chrysanthou, D. Cohen-Or, "Virtual Occluders: An Efficient Intermediate PVS
 * Representation", Eurographics Workshop on Rendering 2000: section 3 (seeds by the solid-angle
 * criterion, the aggregate umbra of a cluster of occluders replaced by one planar occluder that is
 * fully occluded from the whole cell, the dense set and its greedy decimation, figure 6) and
 * section 3.1 (2.5D: the scene cut at a few heights, each slice a 2D problem using the parts of the
 * occluders that reach that height, virtual occluders standing from the ground to the slice's
 * height). docs/virtual-occluders.md says what is followed, what differs and why.
 *
 * Per view cell V (a triangle or a box in xy, eyes between z_lo and z_hi):
 *  1. Occluders: the building footprints cut into convex pieces (ear clipping, then Hertel-Mehlhorn),
 *     each standing from its base to its roof. Pieces within `radius` of the cell whose roof is above
 *     z_hi take part. Seeds: the `seeds` pieces of largest angle seen from the cell's centre (the 2D
 *     solid-angle criterion). Slice heights: up to `slices` of the seeds' roof heights (quantiles).
 *  2. Candidate planes: for every edge of a seed that faces the whole cell, lines parallel to it at
 *     `depths` depths inside the seed (the virtual occluder runs through the block, behind the
 *     facade: the paper places it "behind the object"). On each line L and slice h, the points of L
 *     hidden from every point of V by the pieces reaching h are found (below); every maximal hidden
 *     run is a virtual occluder: a vertical rectangle on L from the ground to h. A run crosses
 *     several buildings and the gaps between them when the buildings in front close the gaps: that
 *     is the fusion of their umbrae, including umbrae that do not intersect (the paper's figure 5).
 *  3. An object is culled when its box lies in the umbra of one virtual occluder (every segment
 *     from V to the box crosses it) and the height condition holds (below). With `keep=N` only the
 *     first N occluders of the greedy decimation (figure 6, weight = objects culled) are used.
 *
 * Hidden points of L (the construction's test, exact up to rounding; closed sets). Frame of L: x
 * along L, y its distance towards V (V in y > 0; a_near, a_far: V's nearest and farthest y). Every
 * sight line from v in V to a point (s, 0) crosses the strip 0 < y < a_near before reaching v, so
 * a piece clipped to the strip [delta, a_near] that the line meets blocks it. Lines through (s, 0)
 * are parametrised by u, where they cross y = ya (ya > a_far): a point q = (qx, qy), 0 < qy < ya,
 * lies on the line (s, u) when u = g_q(s) = (qx - s (1 - m)) / m, m = qy / ya: linear in s. For a
 * fixed s, the lines meeting a convex set are the u between the min and the max of g over its
 * vertices. An interval [s0, s1] of L is hidden when, for every s in it, V's u-interval is covered
 * by the union of the pieces' u-intervals. Over the interval, V's interval lies inside
 * [min of g_v(s0), g_v(s1) over V's vertices, max of them] (min of linear functions is concave,
 * its minimum is at an end), and a piece's interval contains [min_j max(g_j(s0), g_j(s1)),
 * max_j min(g_j(s0), g_j(s1))] (max_s min_j <= min_j max_s, and the converse for max); so covering
 * the first by the union of the second (sorted, swept) proves the interval hidden. Intervals that
 * fail are halved `refine` times. A point of L inside a piece is hidden by that piece itself.
 *
 * Why culling against a virtual occluder S (on L, slice h) is conservative, in 3D. Take an eye E
 * (xy v in V, height e in [z_lo, z_hi]) and a point X of an object's box (xy x, height z). In 2D
 * the segment v-x crosses S at a point s (the umbra test: checked at the vertex pairs of V and of
 * the box, which bound the crossing points, as projections of convex sets), and v-s meets a piece
 * P of the slice at a point p (s is hidden). Along the sight line the height is linear in the
 * distance to L, so with t = dist(v, L) / (dist(v, L) + dist(x, L)) <= t_max = a_far / (a_far +
 * b_min) (b_min: the box's nearest distance beyond L) the height at s lies between
 * min(z_lo, z_lo + (z_min - z_lo) t_max) and max(z_hi, z_hi + (z_max - z_hi) t_max), and at p
 * between those and e. Requiring the upper bound <= h (h >= z_hi) and the lower bound >= the highest
 * base of the slice's pieces puts the line inside P's prism at p: it crosses a wall or the roof of
 * a building before reaching X. That building is not X's object: p lies in front of L, the box
 * wholly beyond it. (This is the paper's argument "a vertical object occluded at a height is
 * occluded at all smaller heights", with the perspective from the cell made exact.)
 *
 * Scope: PRISM and BOX cells of 2.5D scenes (footprints). Scenes without footprints and Quake III
 * cluster cells are refused. Objects are judged by their boxes; trees, cars and 3D occluder meshes
 * do not occlude. Deterministic: every step is a fixed-order computation on the cell's data. */
#include "pvs_internal.h"

#include "core/polygon.h"
#include "scene/scene_internal.h"

#include <math.h>
#include <stdlib.h>

/* fmin and fmax are library calls at -O2 (their NaN rules); no NaN reaches these */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

typedef struct virt_config {
    float radius;     /* metres around the cell: pieces taking part */
    uint32_t seeds;   /* seed pieces per cell */
    uint32_t slices;  /* height slices per cell */
    uint32_t depths;  /* lines per seed edge */
    float step;       /* metres: first intervals along a line near the cell */
    float growth;     /* farther along, intervals of this fraction of the distance */
    uint32_t refine;  /* halvings of an interval that is not proved hidden */
    float min_len;    /* metres: shorter hidden runs are not kept */
    uint32_t keep;    /* 0: every virtual occluder; N: the first N of the greedy decimation */
    bool fuse;        /* also cull against the union of the virtual occluders */
} virt_config;

typedef struct vpiece {
    uint32_t first, count; /* vertices in xy, counter-clockwise, convex */
    double base, roof;
    double x0, y0, x1, y1; /* box */
} vpiece;

typedef struct virt_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    virt_config cfg;
    uint32_t npiece;
    vpiece *pieces;
    double *xy;
    size_t nxy;
    uint32_t nobj;
    const sl_aabb *bounds;
} virt_shared;

/* A candidate line: origin, unit direction t, unit normal n towards the cell. */
typedef struct vline {
    double ox, oy, tx, ty, nx, ny;
    double vx[4], vy[4]; /* the cell's vertices in the line's frame */
    double a_near, a_far;
} vline;

/* A virtual occluder: the stretch [s0, s1] of line `line`, standing from the ground to h. */
typedef struct vocc {
    uint32_t line;
    double s0, s1, h, bmax;
    uint32_t culled; /* decimation weight */
} vocc;

/* A piece in a line's frame, clipped to the strip: vertices in obuf. */
typedef struct vobst {
    uint32_t first, count;
    double x0, x1, y0, y1;
} vobst;

typedef struct keyed {
    double k;
    uint32_t id;
} keyed;

typedef struct ivl {
    double lo, hi;
} ivl;

typedef struct virt_worker {
    virt_shared *sh;
    uint32_t *near;   /* pieces taking part */
    keyed *key;       /* per near piece: sort keys */
    double *heights;
    sl_array lines;   /* vline */
    sl_array vos;     /* vocc */
    sl_array obst;    /* vobst */
    sl_array obuf;    /* double pairs */
    sl_array inside;  /* ivl: stretches of L inside pieces */
    sl_array ivls;    /* ivl: the cover sweep */
    sl_array runs;    /* ivl: hidden stretches of the current line */
    sl_array segs;    /* double[4]: virtual occluders in an object's frame (fuse) */
    uint8_t *culled;  /* per object */
    uint32_t *order;  /* virtual occluders in test order */
    size_t order_cap;
    uint32_t *list;   /* per decimation: objects culled by each occluder (CSR) */
    size_t list_cap;
} virt_worker;

static const char g_help[] =
    "radius=FLOAT (default 1000): metres around the cell within which footprints take part\n"
    "seeds=1..1024 (default 128): seed occluders per cell, by angle seen from the cell's centre (the paper's "
    "solid-angle criterion)\n"
    "slices=1..16 (default 4): height slices per cell (section 3.1), chosen among the seeds' roof heights\n"
    "depths=1..8 (default 1): candidate lines per facing edge of a seed, parallel to it: through the middle of the "
    "seed, then 2, 4, ... times its depth behind the edge\n"
    "step=FLOAT (default 2): metres, first intervals along a line tested for being hidden\n"
    "growth=0..1 (default 0.05): intervals along a line grow to this fraction of their distance from the cell\n"
    "refine=0..8 (default 3): halvings of an interval not proved hidden\n"
    "min_len=FLOAT (default 1): metres, shortest virtual occluder kept\n"
    "keep=0..65535 (default 0): 0 uses the whole dense set; N the first N virtual occluders of the greedy "
    "decimation (figure 6 of the paper, weight = objects culled)\n"
    "fuse=BOOL (default true): an object in no single virtual occluder's umbra is also culled when every sight "
    "line from the cell to it crosses one of them (their umbrae fused the same way; not in the paper)\n";

static sl_status virt_configure(sl_opts *o, void *config, sl_error *err)
{
    virt_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "radius", 1000.0f, 1.0f, 100000.0f, &c->radius, err)) != SL_OK ||
        (st = sl_opts_u32(o, "seeds", 128, 1, 1024, &c->seeds, err)) != SL_OK ||
        (st = sl_opts_u32(o, "slices", 4, 1, 16, &c->slices, err)) != SL_OK ||
        (st = sl_opts_u32(o, "depths", 1, 1, 8, &c->depths, err)) != SL_OK ||
        (st = sl_opts_float(o, "step", 2.0f, 0.01f, 1000.0f, &c->step, err)) != SL_OK ||
        (st = sl_opts_float(o, "growth", 0.05f, 0.0f, 1.0f, &c->growth, err)) != SL_OK ||
        (st = sl_opts_u32(o, "refine", 3, 0, 8, &c->refine, err)) != SL_OK ||
        (st = sl_opts_float(o, "min_len", 1.0f, 0.0f, 1000.0f, &c->min_len, err)) != SL_OK ||
        (st = sl_opts_u32(o, "keep", 0, 0, 65535, &c->keep, err)) != SL_OK ||
        (st = sl_opts_bool(o, "fuse", true, &c->fuse, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void virt_release(void *p)
{
    virt_shared *s = p;
    if (!s)
        return;
    sl_free(&s->a, s->pieces, ((size_t)s->npiece + 1) * sizeof(vpiece));
    sl_free(&s->a, s->xy, (s->nxy + 1) * sizeof(double));
    sl_free(&s->a, s, sizeof *s);
}

/* ---- preparation: convex pieces of the footprints ---- */

static bool push_piece(virt_shared *s, sl_array *pieces, sl_array *xy, const double *v, uint32_t n, double base,
                       double roof)
{
    vpiece pc = {(uint32_t)(xy->count / 2), n, base, roof, INFINITY, INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; i++) {
        pc.x0 = dmin(pc.x0, v[2 * i]), pc.x1 = dmax(pc.x1, v[2 * i]);
        pc.y0 = dmin(pc.y0, v[2 * i + 1]), pc.y1 = dmax(pc.y1, v[2 * i + 1]);
    }
    return sl_array_push(&s->a, xy, sizeof(double), v, 2 * (size_t)n) && sl_array_push(&s->a, pieces, sizeof pc, &pc, 1);
}

/* Convex pieces of footprint f (a counter-clockwise simple polygon). A footprint that cannot be
 * cut (not simple) is left out: fewer occluders only keep more objects. *skipped counts them. */
static sl_status decompose(virt_shared *s, uint32_t f, sl_array *pieces, sl_array *xy, uint64_t *skipped,
                           sl_error *err)
{
    sl_footprint_view fp = sl_scene_footprint(s->scene, f);
    uint32_t n = fp.vertex_count;
    if (n < 3 || !(fp.roof_z > fp.base_z) || sl_scene_footprint_moves(s->scene, f))
        return SL_OK; /* (a moving object's footprint is never an occluder) */
    size_t nn = (size_t)n;
    sl_dvec2 *q = sl_alloc(&s->a, nn * sizeof *q);
    uint32_t *work = sl_alloc(&s->a, nn * sizeof *work);
    uint32_t *tri = sl_alloc(&s->a, 3 * nn * sizeof *tri);
    uint32_t *polys = sl_alloc(&s->a, nn * nn * sizeof *polys);
    uint32_t *len = sl_alloc(&s->a, nn * sizeof *len);
    double *v = sl_alloc(&s->a, 2 * nn * sizeof *v);
    sl_status st = SL_OK;
    if (!q || !work || !tri || !polys || !len || !v) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
        goto done;
    }
    double area = 0;
    for (uint32_t i = 0; i < n; i++) {
        q[i].x = fp.xy[2 * i], q[i].y = fp.xy[2 * i + 1];
        v[2 * i] = q[i].x, v[2 * i + 1] = q[i].y;
    }
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        area += q[i].x * q[j].y - q[j].x * q[i].y;
    }
    if (!(area > 0)) {
        ++*skipped;
        goto done;
    }
    bool convex = true;
    for (uint32_t i = 0; i < n && convex; i++)
        convex = sl_orient2d(q[i].x, q[i].y, q[(i + 1) % n].x, q[(i + 1) % n].y, q[(i + 2) % n].x, q[(i + 2) % n].y) >= 0;
    if (convex) {
        if (!push_piece(s, pieces, xy, v, n, fp.base_z, fp.roof_z))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
        goto done;
    }
    if (!sl_ear_clip(q, n, work, tri)) {
        ++*skipped;
        goto done;
    }
    sl_merge_convex(q, n, tri, polys, len);
    for (uint32_t p = 0; p + 2 < n && st == SL_OK; p++) {
        if (!len[p])
            continue;
        for (uint32_t k = 0; k < len[p]; k++) {
            const sl_dvec2 *c = &q[polys[(size_t)p * n + k]];
            v[2 * k] = c->x, v[2 * k + 1] = c->y;
        }
        if (!push_piece(s, pieces, xy, v, len[p], fp.base_z, fp.roof_z))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
    }
done:
    sl_free(&s->a, q, nn * sizeof *q);
    sl_free(&s->a, work, nn * sizeof *work);
    sl_free(&s->a, tri, 3 * nn * sizeof *tri);
    sl_free(&s->a, polys, nn * nn * sizeof *polys);
    sl_free(&s->a, len, nn * sizeof *len);
    sl_free(&s->a, v, 2 * nn * sizeof *v);
    return st;
}

static sl_status virt_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                              uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads; /* serial */
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        if (vc[i].shape != SL_CELL_PRISM && vc[i].shape != SL_CELL_BOX)
            return sl_fail(err, SL_ERROR_UNSUPPORTED,
                           "virtual: view cell %u is a BSP cluster; virtual occluders need prism or box cells of "
                           "a 2.5D scene (for Quake III maps use --method portal)",
                           i);
    if (sl_scene_footprint_count(scene) == 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "virtual: the scene has no building footprints; virtual occluders are built from 2.5D "
                       "occluders (footprints standing on the ground), so this method does not apply (Quake III "
                       "maps: --method portal; other models: --method gvs, aggressive)");
    virt_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->cfg = *(const virt_config *)config;
    s->nobj = sl_scene_object_count(scene);
    s->bounds = sl_scene_object_bounds_array(scene);
    sl_array pieces = {0}, xy = {0};
    sl_status st = SL_OK;
    uint64_t skipped = 0;
    for (uint32_t f = 0; f < sl_scene_footprint_count(scene) && st == SL_OK; f++)
        st = decompose(s, f, &pieces, &xy, &skipped, err);
    *removed = skipped;
    if (st != SL_OK) {
        sl_array_free(alloc, &pieces, sizeof(vpiece));
        sl_array_free(alloc, &xy, sizeof(double));
        virt_release(s);
        return st;
    }
    s->npiece = (uint32_t)pieces.count;
    s->nxy = xy.count;
    s->pieces = sl_realloc(alloc, pieces.data, pieces.cap * sizeof(vpiece), ((size_t)s->npiece + 1) * sizeof(vpiece));
    s->xy = sl_realloc(alloc, xy.data, xy.cap * sizeof(double), (s->nxy + 1) * sizeof(double));
    if (!s->pieces || !s->xy) {
        if (!s->pieces)
            sl_array_free(alloc, &pieces, sizeof(vpiece));
        if (!s->xy)
            sl_array_free(alloc, &xy, sizeof(double));
        virt_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
    }
    *shared = s;
    return SL_OK;
}

static void virt_worker_destroy(void *p)
{
    virt_worker *w = p;
    if (!w)
        return;
    virt_shared *s = w->sh;
    size_t np = (size_t)s->npiece + 1, no = (size_t)s->nobj + 1;
    sl_free(&s->a, w->near, np * sizeof(uint32_t));
    sl_free(&s->a, w->key, np * sizeof(keyed));
    sl_free(&s->a, w->heights, np * sizeof(double));
    sl_array_free(&s->a, &w->lines, sizeof(vline));
    sl_array_free(&s->a, &w->vos, sizeof(vocc));
    sl_array_free(&s->a, &w->obst, sizeof(vobst));
    sl_array_free(&s->a, &w->obuf, sizeof(double));
    sl_array_free(&s->a, &w->inside, sizeof(ivl));
    sl_array_free(&s->a, &w->ivls, sizeof(ivl));
    sl_array_free(&s->a, &w->runs, sizeof(ivl));
    sl_array_free(&s->a, &w->segs, 4 * sizeof(double));
    sl_free(&s->a, w->culled, no);
    sl_free(&s->a, w->order, w->order_cap * sizeof(uint32_t));
    sl_free(&s->a, w->list, w->list_cap * sizeof(uint32_t));
    sl_free(&s->a, w, sizeof *w);
}

static sl_status virt_worker_create(void *shared, void **out, sl_error *err)
{
    virt_shared *s = shared;
    virt_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
    w->sh = s;
    size_t np = (size_t)s->npiece + 1, no = (size_t)s->nobj + 1;
    w->near = sl_alloc(&s->a, np * sizeof(uint32_t));
    w->key = sl_alloc(&s->a, np * sizeof(keyed));
    w->heights = sl_alloc(&s->a, np * sizeof(double));
    w->culled = sl_alloc(&s->a, no);
    if (!w->near || !w->key || !w->heights || !w->culled) {
        virt_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
    }
    *out = w;
    return SL_OK;
}

/* ---- sorting (total orders: the result never depends on the sort) ---- */

static int cmp_keyed_desc(const void *a, const void *b)
{
    const keyed *x = a, *y = b;
    if (x->k != y->k)
        return x->k > y->k ? -1 : 1;
    return x->id < y->id ? -1 : x->id > y->id;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static int cmp_ivl(const void *a, const void *b)
{
    const ivl *x = a, *y = b;
    if (x->lo != y->lo)
        return x->lo < y->lo ? -1 : 1;
    return x->hi < y->hi ? -1 : x->hi > y->hi;
}

static int cmp_obst(const void *a, const void *b)
{
    const vobst *x = a, *y = b;
    if (x->x0 != y->x0)
        return x->x0 < y->x0 ? -1 : 1;
    return x->first < y->first ? -1 : x->first > y->first;
}

/* ---- the hidden stretches of a line ---- */

typedef struct line_ctx {
    const vline *L;
    double ya;        /* the u line: y = ya beyond the cell */
    double delta;     /* pieces are clipped to y >= delta (g is singular at y = 0) */
    const vobst *ob;
    size_t nob;
    const double *buf;
    const ivl *inside;
    size_t ninside;
} line_ctx;

static inline double gq(double qx, double qy, double ya, double s)
{
    double m = qy / ya;
    return (qx - s * (1 - m)) / m;
}

/* Is every point of [s0, s1] on L hidden from the cell (see the file's comment)? */
static bool interval_hidden(virt_worker *w, const line_ctx *c, double s0, double s1)
{
    /* inside the pieces crossing L (merged stretches, sorted): hidden by the pieces themselves */
    size_t lo_i = 0, hi_i = c->ninside;
    while (lo_i < hi_i) {
        size_t mid = (lo_i + hi_i) / 2;
        if (c->inside[mid].hi < s1)
            lo_i = mid + 1;
        else
            hi_i = mid;
    }
    if (lo_i < c->ninside && c->inside[lo_i].lo <= s0)
        return true;
    const vline *L = c->L;
    double dlo = INFINITY, dhi = -INFINITY;
    double cvx0 = INFINITY, cvx1 = -INFINITY;
    for (int i = 0; i < 4; i++) {
        double a = gq(L->vx[i], L->vy[i], c->ya, s0), b = gq(L->vx[i], L->vy[i], c->ya, s1);
        dlo = dmin(dlo, dmin(a, b)), dhi = dmax(dhi, dmax(a, b));
        cvx0 = dmin(cvx0, L->vx[i]), cvx1 = dmax(cvx1, L->vx[i]);
    }
    w->ivls.count = 0;
    const double reach_hi = dmax(s1, cvx1);
    for (size_t k = 0; k < c->nob; k++) {
        const vobst *o = &c->ob[k];
        if (o->x0 > reach_hi)
            break; /* sorted by x0 */
        /* speed only: the lines from [s0, s1] to the cell at heights y in [o->y0, o->y1] lie at x
         * between the lerps of the ends; a piece left out only keeps more points visible */
        double f0 = o->y0 / L->a_far, f1 = dmin(1.0, o->y1 / L->a_near);
        double lx = dmin(dmin(s0 + (cvx0 - s0) * f0, s0 + (cvx0 - s0) * f1), dmin(s1 + (cvx0 - s1) * f0, s1 + (cvx0 - s1) * f1));
        double hx = dmax(dmax(s0 + (cvx1 - s0) * f0, s0 + (cvx1 - s0) * f1), dmax(s1 + (cvx1 - s1) * f0, s1 + (cvx1 - s1) * f1));
        if (o->x1 < lx || o->x0 > hx)
            continue;
        const double *v = c->buf + 2 * (size_t)o->first;
        double lo = INFINITY, hi = -INFINITY;
        for (uint32_t j = 0; j < o->count; j++) {
            double a = gq(v[2 * j], v[2 * j + 1], c->ya, s0), b = gq(v[2 * j], v[2 * j + 1], c->ya, s1);
            lo = dmin(lo, dmax(a, b));
            hi = dmax(hi, dmin(a, b));
        }
        /* a margin of rounding: the interval is only ever made smaller */
        double m = 1e-9 * (1 + fabs(lo) + fabs(hi));
        lo += m, hi -= m;
        if (!(lo <= hi) || hi < dlo || lo > dhi)
            continue;
        ivl iv = {lo, hi};
        if (!sl_array_push(&w->sh->a, &w->ivls, sizeof iv, &iv, 1))
            return false; /* out of memory: not proved (the caller's result stays conservative) */
    }
    ivl *iv = w->ivls.data;
    size_t n = w->ivls.count;
    if (n == 0)
        return false;
    qsort(iv, n, sizeof *iv, cmp_ivl);
    double reach = dlo;
    for (size_t i = 0; i < n && reach < dhi; i++) {
        if (iv[i].lo > reach)
            return false;
        reach = dmax(reach, iv[i].hi);
    }
    return reach >= dhi;
}

/* Hidden sub-intervals of [s0, s1] appended to w->runs (in order, merged when they touch). */
static bool scan(virt_worker *w, const line_ctx *c, double s0, double s1, uint32_t depth)
{
    if (interval_hidden(w, c, s0, s1)) {
        ivl *r = w->runs.count ? &((ivl *)w->runs.data)[w->runs.count - 1] : NULL;
        if (r && r->hi == s0) {
            r->hi = s1;
            return true;
        }
        ivl iv = {s0, s1};
        return sl_array_push(&w->sh->a, &w->runs, sizeof iv, &iv, 1) != NULL;
    }
    if (depth == 0)
        return true;
    double mid = 0.5 * (s0 + s1);
    return scan(w, c, s0, mid, depth - 1) && scan(w, c, mid, s1, depth - 1);
}

/* The virtual occluders of line li at slice h: pieces of the slice (near[0..nn) with roof >= h)
 * in the line's frame, clipped to the strip, then the scan of the window. */
static bool line_occluders(virt_worker *w, uint32_t li, uint32_t nn, double h, double bmax, double cx, double cy)
{
    virt_shared *s = w->sh;
    const vline *L = &((const vline *)w->lines.data)[li];
    w->obst.count = 0;
    w->obuf.count = 0;
    w->inside.count = 0;
    const double delta = 1e-3;
    double px[80], py[80], qx[84], qy[84], rx[88], ry[88];
    for (uint32_t k = 0; k < nn; k++) {
        const vpiece *pc = &s->pieces[w->near[k]];
        if (pc->roof < h || pc->count > 80)
            continue;
        const double *v = s->xy + 2 * (size_t)pc->first;
        double ymin = INFINITY, ymax = -INFINITY;
        for (uint32_t i = 0; i < pc->count; i++) {
            double dx = v[2 * i] - L->ox, dy = v[2 * i + 1] - L->oy;
            px[i] = dx * L->tx + dy * L->ty;
            py[i] = dx * L->nx + dy * L->ny;
            ymin = dmin(ymin, py[i]), ymax = dmax(ymax, py[i]);
        }
        if (ymax <= delta || ymin >= L->a_near)
            continue;
        /* the frame is a rotation: the piece stays convex and counter-clockwise when (t, n) is
         * right-handed; the clips below do not depend on the orientation */
        if (ymin <= 0 && ymax >= 0) {
            double xl, xr, hv[160];
            for (uint32_t i = 0; i < pc->count; i++)
                hv[2 * i] = px[i], hv[2 * i + 1] = py[i];
            if (sl_band_extent(hv, pc->count, 0, 0, &xl, &xr)) {
                ivl iv = {xl, xr};
                if (!sl_array_push(&s->a, &w->inside, sizeof iv, &iv, 1))
                    return false;
            }
        }
        uint32_t m = sl_clip_half(px, py, pc->count, 0, 1, delta, qx, qy, 84);
        m = sl_clip_half(qx, qy, m, 0, -1, -L->a_near, rx, ry, 88);
        if (m < 2)
            continue;
        vobst o = {(uint32_t)(w->obuf.count / 2), m, INFINITY, -INFINITY, INFINITY, -INFINITY};
        double *dst = sl_array_push(&s->a, &w->obuf, sizeof(double), NULL, 2 * (size_t)m);
        if (!dst)
            return false;
        for (uint32_t i = 0; i < m; i++) {
            dst[2 * i] = rx[i], dst[2 * i + 1] = ry[i];
            o.x0 = dmin(o.x0, rx[i]), o.x1 = dmax(o.x1, rx[i]);
            o.y0 = dmin(o.y0, ry[i]), o.y1 = dmax(o.y1, ry[i]);
        }
        if (!sl_array_push(&s->a, &w->obst, sizeof o, &o, 1))
            return false;
    }
    if (w->obst.count == 0 && w->inside.count == 0)
        return true;
    qsort(w->obst.data, w->obst.count, sizeof(vobst), cmp_obst);
    /* the stretches inside pieces, merged where they overlap or touch: sorted, disjoint */
    if (w->inside.count) {
        ivl *in = w->inside.data;
        qsort(in, w->inside.count, sizeof *in, cmp_ivl);
        size_t m = 0;
        for (size_t i = 1; i < w->inside.count; i++) {
            if (in[i].lo <= in[m].hi)
                in[m].hi = dmax(in[m].hi, in[i].hi);
            else
                in[++m] = in[i];
        }
        w->inside.count = m + 1;
    }
    line_ctx c = {L, L->a_far + 1.0, delta, w->obst.data, w->obst.count, w->obuf.data, w->inside.data,
                  w->inside.count};
    /* the window: the stretch of L within radius of the cell's centre */
    double ccx = (cx - L->ox) * L->tx + (cy - L->oy) * L->ty, ccy = (cx - L->ox) * L->nx + (cy - L->oy) * L->ny;
    double R = s->cfg.radius;
    if (fabs(ccy) >= R)
        return true;
    double half = sqrt(R * R - ccy * ccy);
    /* intervals of `step` near the cell, growing with the distance along L (by `growth` of it):
     * far away a stretch is hidden or not over lengths that grow with the distance */
    const double step = s->cfg.step, growth = s->cfg.growth;
    w->runs.count = 0;
    double left = ccx;
    while (left > ccx - half)
        left -= dmax(step, growth * (ccx - left));
    /* from the leftmost point, the same breakpoints back to ccx, then on to the right */
    double x = left;
    while (x < ccx + half) {
        double d = fabs(x - ccx), len = dmax(step, growth * d);
        double nx = x + len;
        if (x < ccx && nx > ccx)
            nx = ccx;
        if (!scan(w, &c, x, nx, s->cfg.refine))
            return false;
        x = nx;
    }
    const ivl *r = w->runs.data;
    for (size_t i = 0; i < w->runs.count; i++) {
        if (!(r[i].hi - r[i].lo >= s->cfg.min_len))
            continue;
        vocc vo = {li, r[i].lo, r[i].hi, h, bmax, 0};
        if (!sl_array_push(&s->a, &w->vos, sizeof vo, &vo, 1))
            return false;
    }
    return true;
}

/* May virtual occluder vo hide (part of) box b from the cell (z range zlo..zhi)? The box wholly
 * beyond the occluder's line and the height conditions of the file's comment. The box's corners in
 * the line's frame go to bx, by. */
static bool vo_usable(const virt_worker *w, const vocc *vo, const sl_aabb *b, double zlo, double zhi, double *bx,
                      double *by)
{
    const vline *L = &((const vline *)w->lines.data)[vo->line];
    const double cx[4] = {b->min.x, b->max.x, b->max.x, b->min.x}, cy[4] = {b->min.y, b->min.y, b->max.y, b->max.y};
    double bmin = INFINITY;
    for (int j = 0; j < 4; j++) {
        double dx = cx[j] - L->ox, dy = cy[j] - L->oy;
        by[j] = dx * L->nx + dy * L->ny;
        if (!(by[j] < 0))
            return false;
        bx[j] = dx * L->tx + dy * L->ty;
        bmin = dmin(bmin, -by[j]);
    }
    /* heights: the sight lines cross L between the bounds of the file's comment */
    double tmax = L->a_far / (L->a_far + bmin);
    double top = zhi + dmax(0.0, (double)b->max.z - zhi) * tmax;
    double low = zlo + dmin(0.0, (double)b->min.z - zlo) * tmax;
    return top <= vo->h && low >= vo->bmax;
}

/* Is the box b culled by virtual occluder vo alone (its umbra holds the box)? */
static bool vo_culls(const virt_worker *w, const vocc *vo, const sl_aabb *b, uint32_t nv, double zlo, double zhi)
{
    double bx[4], by[4];
    if (!vo_usable(w, vo, b, zlo, zhi, bx, by))
        return false;
    const vline *L = &((const vline *)w->lines.data)[vo->line];
    /* every segment from the cell to the box crosses L within [s0, s1]: the extremes of the crossing
     * points are at vertex pairs */
    for (uint32_t i = 0; i < nv; i++) {
        double vx = L->vx[i], vy = L->vy[i];
        for (int j = 0; j < 4; j++) {
            double x = vx + (bx[j] - vx) * (vy / (vy - by[j]));
            if (!(x >= vo->s0 && x <= vo->s1))
                return false;
        }
    }
    return true;
}

/* ---- fuse: the union of the virtual occluders ----
 * Frame of a separating line between the cell and the box: X along it, Y towards the cell (the box
 * in Y <= yb1, the cell in Y >= yv0 > yb1). A sight line is parametrised by w, where it crosses
 * Y = yw (beyond the box) and u, where it crosses Y = yu (beyond the cell); a point (qx, qy) lies on
 * it when u = g_q(w), as for the hidden points of a line. Every usable occluder, clipped to the
 * strip yb1 <= Y <= yv0, blocks the lines through it there: a crossing point in the strip lies
 * between the eye and the box, it is hidden from the cell at the occluder's slice, and the occluder's
 * height conditions hold for the box. The box is culled when, for every w, the lines meeting both
 * the cell and the box are covered by the occluders' u-intervals (the same bounds over intervals of
 * w as along a line). */
typedef struct fuse_ctx {
    double vx[4], vy[4], bx[4], by[4];
    uint32_t nv;
    double ya;
    const double *seg;
    size_t nseg;
} fuse_ctx;

static bool fuse_piece(virt_worker *w, const fuse_ctx *c, double w0, double w1, uint32_t depth)
{
    double lv = INFINITY, hv = -INFINITY, lb = INFINITY, hb = -INFINITY;
    for (uint32_t i = 0; i < c->nv; i++) {
        double a = gq(c->vx[i], c->vy[i], c->ya, w0), b = gq(c->vx[i], c->vy[i], c->ya, w1);
        lv = dmin(lv, dmin(a, b)), hv = dmax(hv, dmax(a, b));
    }
    for (int j = 0; j < 4; j++) {
        double a = gq(c->bx[j], c->by[j], c->ya, w0), b = gq(c->bx[j], c->by[j], c->ya, w1);
        lb = dmin(lb, dmin(a, b)), hb = dmax(hb, dmax(a, b));
    }
    double dlo = dmax(lv, lb), dhi = dmin(hv, hb);
    bool covered = dlo > dhi; /* no sight line here */
    if (!covered) {
        w->ivls.count = 0;
        for (size_t k = 0; k < c->nseg; k++) {
            const double *q = c->seg + 4 * k;
            double a0 = gq(q[0], q[1], c->ya, w0), a1 = gq(q[0], q[1], c->ya, w1);
            double b0 = gq(q[2], q[3], c->ya, w0), b1 = gq(q[2], q[3], c->ya, w1);
            double lo = dmin(dmax(a0, a1), dmax(b0, b1)), hi = dmax(dmin(a0, a1), dmin(b0, b1));
            double m = 1e-9 * (1 + fabs(lo) + fabs(hi));
            lo += m, hi -= m;
            if (!(lo <= hi) || hi < dlo || lo > dhi)
                continue;
            ivl iv = {lo, hi};
            if (!sl_array_push(&w->sh->a, &w->ivls, sizeof iv, &iv, 1))
                return false;
        }
        ivl *iv = w->ivls.data;
        size_t n = w->ivls.count;
        if (n) {
            qsort(iv, n, sizeof *iv, cmp_ivl);
            double reach = dlo;
            for (size_t i = 0; i < n && reach < dhi && iv[i].lo <= reach; i++)
                reach = dmax(reach, iv[i].hi);
            covered = reach >= dhi;
        }
    }
    if (covered || depth == 0)
        return covered;
    double mid = 0.5 * (w0 + w1);
    return fuse_piece(w, c, w0, mid, depth - 1) && fuse_piece(w, c, mid, w1, depth - 1);
}

/* Is box b hidden from the cell (poly, nv vertices) by the union of the occluders order[0..nuse)? */
static bool union_culls(virt_worker *w, const sl_aabb *b, const double *poly, uint32_t nv, double zlo, double zhi,
                        size_t nuse)
{
    virt_shared *s = w->sh;
    const double cxs[4] = {b->min.x, b->max.x, b->max.x, b->min.x}, cys[4] = {b->min.y, b->min.y, b->max.y, b->max.y};
    /* a separating direction N (from the box towards the cell): the centres' difference, else an
     * edge normal of either (separating axes of two convex polygons) */
    double cand[2 * 9];
    uint32_t ncand = 0;
    double pcx = 0, pcy = 0;
    for (uint32_t i = 0; i < nv; i++)
        pcx += poly[2 * i] / nv, pcy += poly[2 * i + 1] / nv;
    cand[2 * ncand] = pcx - 0.5 * (b->min.x + b->max.x), cand[2 * ncand + 1] = pcy - 0.5 * (b->min.y + b->max.y), ncand++;
    for (uint32_t i = 0; i < nv; i++) {
        const double *p = poly + 2 * i, *q = poly + 2 * ((i + 1) % nv);
        cand[2 * ncand] = -(q[1] - p[1]), cand[2 * ncand + 1] = q[0] - p[0], ncand++; /* inward of a CCW cell */
    }
    const double bn[4][2] = {{0, -1}, {1, 0}, {0, 1}, {-1, 0}};
    for (int j = 0; j < 4; j++)
        cand[2 * ncand] = bn[j][0], cand[2 * ncand + 1] = bn[j][1], ncand++;
    double Nx = 0, Ny = 0, yv0 = 0, yv1 = 0, yb0 = 0, yb1 = 0;
    bool found = false;
    for (uint32_t k = 0; k < ncand && !found; k++) {
        double l = sqrt(cand[2 * k] * cand[2 * k] + cand[2 * k + 1] * cand[2 * k + 1]);
        if (!(l > 0))
            continue;
        Nx = cand[2 * k] / l, Ny = cand[2 * k + 1] / l;
        yv0 = INFINITY, yv1 = -INFINITY, yb0 = INFINITY, yb1 = -INFINITY;
        for (uint32_t i = 0; i < nv; i++) {
            double y = poly[2 * i] * Nx + poly[2 * i + 1] * Ny;
            yv0 = dmin(yv0, y), yv1 = dmax(yv1, y);
        }
        for (int j = 0; j < 4; j++) {
            double y = cxs[j] * Nx + cys[j] * Ny;
            yb0 = dmin(yb0, y), yb1 = dmax(yb1, y);
        }
        found = yv0 - yb1 > 1e-6;
    }
    if (!found)
        return false;
    const double Tx = -Ny, Ty = Nx, yw = yb0 - 1, yu = yv1 + 1;
    fuse_ctx c = {.nv = nv, .ya = yu - yw};
    for (uint32_t i = 0; i < nv; i++) {
        c.vx[i] = poly[2 * i] * Tx + poly[2 * i + 1] * Ty;
        c.vy[i] = poly[2 * i] * Nx + poly[2 * i + 1] * Ny - yw;
    }
    for (int j = 0; j < 4; j++) {
        c.bx[j] = cxs[j] * Tx + cys[j] * Ty;
        c.by[j] = cxs[j] * Nx + cys[j] * Ny - yw;
    }
    /* the usable occluders, clipped to the strip and to the lines' reach */
    double xlo = INFINITY, xhi = -INFINITY;
    for (uint32_t i = 0; i < nv; i++)
        xlo = dmin(xlo, c.vx[i]), xhi = dmax(xhi, c.vx[i]);
    for (int j = 0; j < 4; j++)
        xlo = dmin(xlo, c.bx[j]), xhi = dmax(xhi, c.bx[j]);
    w->segs.count = 0;
    const vocc *vos = w->vos.data;
    for (size_t i = 0; i < nuse; i++) {
        const vocc *vo = &vos[w->order[i]];
        double lx[4], ly[4];
        if (!vo_usable(w, vo, b, zlo, zhi, lx, ly))
            continue;
        const vline *L = &((const vline *)w->lines.data)[vo->line];
        double p0x = L->ox + L->tx * vo->s0, p0y = L->oy + L->ty * vo->s0;
        double p1x = L->ox + L->tx * vo->s1, p1y = L->oy + L->ty * vo->s1;
        double ax = p0x * Tx + p0y * Ty, ay = p0x * Nx + p0y * Ny, bx = p1x * Tx + p1y * Ty, by = p1x * Nx + p1y * Ny;
        /* clip to yb1 <= Y <= yv0 (a shorter occluder only blocks fewer lines) */
        double t0 = 0, t1 = 1, dy = by - ay;
        if (dy == 0) {
            if (ay < yb1 || ay > yv0)
                continue;
        } else {
            double ta = (yb1 - ay) / dy, tb = (yv0 - ay) / dy;
            if (ta > tb) {
                double t = ta;
                ta = tb, tb = t;
            }
            t0 = dmax(t0, ta), t1 = dmin(t1, tb);
            if (!(t0 <= t1))
                continue;
        }
        double q[4] = {ax + (bx - ax) * t0, ay + dy * t0, ax + (bx - ax) * t1, ay + dy * t1};
        /* rounding of the clip: keep the ends inside the strip */
        q[1] = dmin(dmax(q[1], yb1), yv0) - yw, q[3] = dmin(dmax(q[3], yb1), yv0) - yw;
        if (dmax(q[0], q[2]) < xlo || dmin(q[0], q[2]) > xhi)
            continue;
        if (!sl_array_push(&s->a, &w->segs, 4 * sizeof(double), q, 1))
            return false;
    }
    if (w->segs.count == 0)
        return false;
    c.seg = w->segs.data;
    c.nseg = w->segs.count;
    /* the w range of the sight lines: crossings of Y = yw by the lines through vertex pairs */
    double wlo = INFINITY, whi = -INFINITY;
    for (uint32_t i = 0; i < nv; i++)
        for (int j = 0; j < 4; j++) {
            double f = (0 - c.by[j]) / (c.vy[i] - c.by[j]);
            double x = c.bx[j] + (c.vx[i] - c.bx[j]) * f;
            wlo = dmin(wlo, x), whi = dmax(whi, x);
        }
    const uint32_t pieces = 8;
    double dw = (whi - wlo) / pieces;
    for (uint32_t k = 0; k < pieces; k++) {
        double w0 = wlo + dw * k, w1 = k + 1 == pieces ? whi : wlo + dw * (k + 1);
        if (!fuse_piece(w, &c, w0, w1, s->cfg.refine))
            return false;
    }
    return true;
}

static sl_status virt_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    virt_worker *w = worker;
    virt_shared *s = w->sh;
    const virt_config *cfg = &s->cfg;
    const sl_viewcell *vc = &sl_viewcells_data(s->cells)[cell];
    double poly[8];
    uint32_t nv;
    if (vc->shape == SL_CELL_PRISM) {
        for (int i = 0; i < 3; i++)
            poly[2 * i] = vc->tri[i].x, poly[2 * i + 1] = vc->tri[i].y;
        nv = 3;
    } else {
        const sl_aabb *b = &vc->bounds;
        double q[8] = {b->min.x, b->min.y, b->max.x, b->min.y, b->max.x, b->max.y, b->min.x, b->max.y};
        memcpy(poly, q, sizeof q);
        nv = 4;
    }
    double cx = 0, cy = 0;
    for (uint32_t i = 0; i < nv; i++)
        cx += poly[2 * i], cy += poly[2 * i + 1];
    cx /= nv, cy /= nv;
    const double zlo = vc->z_min, zhi = vc->z_max;
    /* 1. the pieces taking part, the seeds and the slices */
    uint32_t nn = 0;
    const double R = cfg->radius;
    for (uint32_t k = 0; k < s->npiece; k++) {
        const vpiece *pc = &s->pieces[k];
        double dx = dmax(0.0, dmax(pc->x0 - cx, cx - pc->x1)), dy = dmax(0.0, dmax(pc->y0 - cy, cy - pc->y1));
        if (dx * dx + dy * dy > R * R || !(pc->roof > zhi))
            continue;
        /* a piece meeting the cell's box would cross the cell (cells are free space): left out */
        w->near[nn++] = k;
    }
    uint32_t nk = 0;
    for (uint32_t i = 0; i < nn; i++) {
        const vpiece *pc = &s->pieces[w->near[i]];
        const double *v = s->xy + 2 * (size_t)pc->first;
        /* the angle the piece spans seen from the centre (relative to its first vertex) */
        double rx = v[0] - cx, ry = v[1] - cy, amin = 0, amax = 0;
        bool ok = rx != 0 || ry != 0;
        for (uint32_t j = 1; j < pc->count && ok; j++) {
            double dx = v[2 * j] - cx, dy = v[2 * j + 1] - cy;
            double a = atan2(rx * dy - ry * dx, rx * dx + ry * dy);
            amin = dmin(amin, a), amax = dmax(amax, a);
        }
        if (!ok || !(amax - amin < M_PI))
            continue;
        w->key[nk++] = (keyed){amax - amin, w->near[i]};
    }
    qsort(w->key, nk, sizeof(keyed), cmp_keyed_desc);
    uint32_t nseed = nk < cfg->seeds ? nk : cfg->seeds;
    for (uint32_t i = 0; i < nseed; i++)
        w->heights[i] = s->pieces[w->key[i].id].roof;
    qsort(w->heights, nseed, sizeof(double), cmp_double);
    uint32_t nh = 0;
    for (uint32_t i = 0; i < nseed; i++)
        if (nh == 0 || w->heights[i] != w->heights[nh - 1])
            w->heights[nh++] = w->heights[i];
    double slice[16];
    uint32_t nslice = 0;
    if (nh <= cfg->slices) {
        for (uint32_t i = 0; i < nh; i++)
            slice[nslice++] = w->heights[i];
    } else {
        for (uint32_t k = 0; k < cfg->slices; k++) {
            uint32_t i = cfg->slices == 1 ? 0 : (uint32_t)(((uint64_t)k * (nh - 1)) / (cfg->slices - 1));
            if (nslice == 0 || w->heights[i] != slice[nslice - 1])
                slice[nslice++] = w->heights[i];
        }
    }
    /* 2. candidate lines: for each seed edge facing the whole cell, lines parallel to it inside the
     * seed */
    w->lines.count = 0;
    w->vos.count = 0;
    for (uint32_t i = 0; i < nseed; i++) {
        const vpiece *pc = &s->pieces[w->key[i].id];
        const double *v = s->xy + 2 * (size_t)pc->first;
        for (uint32_t e = 0; e < pc->count; e++) {
            const double *p = v + 2 * e, *q = v + 2 * ((e + 1) % pc->count);
            double dx = q[0] - p[0], dy = q[1] - p[1], len = sqrt(dx * dx + dy * dy);
            if (!(len > 1e-6))
                continue;
            double tx = dx / len, ty = dy / len, nx = ty, ny = -tx; /* outward normal of a CCW polygon */
            bool faces = true;
            for (uint32_t j = 0; j < nv && faces; j++)
                faces = (poly[2 * j] - p[0]) * nx + (poly[2 * j + 1] - p[1]) * ny > 1e-6;
            if (!faces)
                continue;
            double depth = 0;
            for (uint32_t j = 0; j < pc->count; j++)
                depth = dmax(depth, -((v[2 * j] - p[0]) * nx + (v[2 * j + 1] - p[1]) * ny));
            for (uint32_t k = 0; k < cfg->depths; k++) {
                double d = k == 0 ? 0.5 * depth : depth * ldexp(1.0, (int)k);
                vline L = {p[0] - nx * d, p[1] - ny * d, tx, ty, nx, ny, {0}, {0}, INFINITY, -INFINITY};
                for (uint32_t j = 0; j < 4; j++) {
                    uint32_t jj = j < nv ? j : nv - 1;
                    double ux = poly[2 * jj] - L.ox, uy = poly[2 * jj + 1] - L.oy;
                    L.vx[j] = ux * tx + uy * ty;
                    L.vy[j] = ux * nx + uy * ny;
                    L.a_near = dmin(L.a_near, L.vy[j]), L.a_far = dmax(L.a_far, L.vy[j]);
                }
                if (!(L.a_near > 1e-3))
                    continue;
                /* a line already there (collinear facades of a row of buildings) is not scanned twice */
                bool dup = false;
                const vline *ls = w->lines.data;
                for (size_t m = 0; m < w->lines.count && !dup; m++)
                    dup = fabs(ls[m].tx * ty - ls[m].ty * tx) < 1e-6 && ls[m].tx * tx + ls[m].ty * ty > 0 &&
                          fabs((L.ox - ls[m].ox) * nx + (L.oy - ls[m].oy) * ny) < 0.05;
                if (dup)
                    continue;
                if (!sl_array_push(&s->a, &w->lines, sizeof L, &L, 1))
                    return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
            }
        }
    }
    uint64_t work = 0;
    for (uint32_t k = 0; k < nslice; k++) {
        double bmax = -INFINITY;
        for (uint32_t i = 0; i < nn; i++)
            if (s->pieces[w->near[i]].roof >= slice[k])
                bmax = dmax(bmax, s->pieces[w->near[i]].base);
        for (uint32_t li = 0; li < (uint32_t)w->lines.count; li++) {
            if (!line_occluders(w, li, nn, slice[k], bmax, cx, cy))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
            work++;
        }
    }
    /* 3. culling against the virtual occluders: longest first (with keep, the decimation's order) */
    const size_t nvo = w->vos.count;
    vocc *vos = w->vos.data;
    if (w->order_cap < nvo + 1) {
        uint32_t *o = sl_realloc(&s->a, w->order, w->order_cap * sizeof(uint32_t), (nvo + 1) * sizeof(uint32_t));
        if (!o)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
        w->order = o, w->order_cap = nvo + 1;
    }
    keyed *vk = sl_alloc(&s->a, (nvo + 1) * sizeof(keyed));
    if (!vk)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "virtual: out of memory");
    for (size_t i = 0; i < nvo; i++)
        vk[i] = (keyed){vos[i].s1 - vos[i].s0, (uint32_t)i};
    qsort(vk, nvo, sizeof(keyed), cmp_keyed_desc);
    for (size_t i = 0; i < nvo; i++)
        w->order[i] = vk[i].id;
    sl_free(&s->a, vk, (nvo + 1) * sizeof(keyed));
    size_t nuse = nvo;
    if (cfg->keep) {
        /* greedy decimation (the paper's figure 6): weight = objects an occluder culls that the ones
         * chosen before do not */
        memset(w->culled, 0, s->nobj);
        size_t chosen = 0;
        while (chosen < cfg->keep && chosen < nvo) {
            size_t best = chosen;
            uint32_t best_w = 0;
            for (size_t i = chosen; i < nvo; i++) {
                uint32_t c = 0;
                for (uint32_t o = 0; o < s->nobj; o++)
                    if (!w->culled[o] && vo_culls(w, &vos[w->order[i]], &s->bounds[o], nv, zlo, zhi))
                        c++;
                if (c > best_w)
                    best_w = c, best = i;
            }
            if (best_w == 0)
                break;
            uint32_t t = w->order[chosen];
            w->order[chosen] = w->order[best];
            w->order[best] = t;
            for (uint32_t o = 0; o < s->nobj; o++)
                if (!w->culled[o] && vo_culls(w, &vos[w->order[chosen]], &s->bounds[o], nv, zlo, zhi))
                    w->culled[o] = 1;
            chosen++;
        }
        nuse = chosen;
    }
    uint32_t n = 0;
    for (uint32_t o = 0; o < s->nobj; o++) {
        bool hidden = false;
        for (size_t i = 0; i < nuse && !hidden; i++)
            hidden = vo_culls(w, &vos[w->order[i]], &s->bounds[o], nv, zlo, zhi);
        if (!hidden && cfg->fuse)
            hidden = union_culls(w, &s->bounds[o], poly, nv, zlo, zhi, nuse);
        if (!hidden)
            out->ids[n++] = o;
    }
    out->count = n;
    out->work = work;
    return SL_OK;
}

const sl_pvs_method sl_pvs_method_virtual = {
    .name = "virtual",
    .summary = "virtual occluders: per cell, hidden stretches of planes behind groups of occluders (their fused "
               "umbra) in height slices, objects culled against them (Koltun, Chrysanthou, Cohen-Or 2000); "
               "conservative for 2.5D scenes",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(virt_config),
    .configure = virt_configure,
    .prepare = virt_prepare,
    .worker_create = virt_worker_create,
    .cell = virt_cell,
    .worker_destroy = virt_worker_destroy,
    .release = virt_release,
    .notice = NULL,
};

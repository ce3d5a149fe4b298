/* gvs: guided visibility sampling from a view cell, and the `gvs` PVS method.
 *
 * P. Wonka, M. Wimmer, K. Zhou, S. Maierhofer, G. Hesina, A. Reshetov, "Guided Visibility
 * Sampling", ACM TOG 25(3), SIGGRAPH 2006 = chapter 5 of M. Wimmer's habilitation (TU Wien 2007):
 *  - 5.3.1 random rays: u = xi1, v = xi2 on a cell face, phi = 2 pi xi3, theta = asin xi4, with
 *    independent Halton sequences (face picked by area, an assumption: the paper does not say);
 *  - 5.3.2 adaptive border sampling (ABS): the first time a ray x from x_p hits triangle t, t is
 *    enlarged in ray space to a 9-vertex polygon t' (three vertices per corner, eps * |p_i - x_p|
 *    off the corner along the two edge normals and their bisector, all perpendicular to the ray),
 *    rays from the same origin go to the 9 vertices, and every edge of t' is subdivided
 *    recursively while its end rays hit different triangles far enough apart;
 *  - 5.3.3 reverse sampling (RS): an ABS ray that hits a triangle t'' closer than the plane of t
 *    by more than Delta is blocked; the plane through x_p, hit(x) and hit(x_old) cuts t'' in a
 *    segment, p_new is taken just outside t'' at an end of it, and a new ray from the view cell
 *    (where the line predicted(x) -> p_new, extended, meets the cell) through p_new toward
 *    predicted(x) is cast; it is discarded when the line misses the cell;
 *  - 5.3.4 the combination: a queue of (origin, new triangle) pairs; ABS runs from the origin that
 *    found the triangle, so triangles found by RS are explored from the new origin;
 *  - 5.3.5 termination: at most min_new new triangles per window of rays, or max_rays in all
 *    (50 per 1M and 10M in the paper);
 *  - 5.5.6 the progressive variant (option `initial`) and per-object results.
 * Choices the paper leaves open are listed in docs/gvs.md with the reasons (miss handling, Delta,
 * the world-space subdivision threshold, which end of the RS segment, the ABS angular floor).
 *
 * Scope: any triangle scene; PRISM and BOX cells (origins on the boundary, as in the paper, or in
 * the volume) and Quake III CLUSTER cells (origins in the volume: a cluster is a union of BSP
 * leaves, not a convex polyhedron). Deterministic: a cell's result is a function of the scene, the
 * cells, the options and the cell index; nothing depends on threads or on earlier calls. */
#include "gvs_internal.h"

#include "core/dvec3.h"
#include "halton.h"
#include "pvs_internal.h"

#include <math.h>
#include <stdlib.h>

/* ---- double vectors: src/core/dvec3.h ---- */

/* ---- options ---- */

sl_gvs_options sl_gvs_defaults(void)
{
    sl_gvs_options o;
    memset(&o, 0, sizeof o);
    o.sampler = SL_GVS_GUIDED;
    o.origins = SL_GVS_ORIGINS_AUTO;
    o.eps = 5e-5;
    o.rs_delta = 0.01;
    o.window = 1000000;
    o.min_new = 50;
    o.max_rays = 10000000;
    o.initial = 0;
    o.batch = 64;
    o.max_depth = 32;
    o.auto_visible = true;
    o.log_curve = true;
    o.seed = 0;
    return o;
}

sl_status sl_gvs_options_check(const sl_gvs_options *o, sl_error *err)
{
    if (!o)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: options are NULL");
    if (o->sampler > SL_GVS_RANDOM)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: sampler %u is neither guided (0) nor random (1)",
                       o->sampler);
    if (o->origins > SL_GVS_ORIGINS_VOLUME)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: origins %u is not auto (0), boundary (1) or volume (2)",
                       o->origins);
    if (!isfinite(o->eps) || !(o->eps >= 1e-9 && o->eps <= 0.1))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: eps %g is outside [1e-9, 0.1]", o->eps);
    if (!isfinite(o->rs_delta) || !(o->rs_delta >= 0 && o->rs_delta <= 100))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: rs_delta %g is outside [0, 100]", o->rs_delta);
    if (o->window == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: window must be at least 1 ray");
    if (o->max_rays == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: max_rays must be at least 1");
    if (o->batch == 0 || o->batch > 4096)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: batch %u is outside [1, 4096]", o->batch);
    if (o->max_depth > 64)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: max_depth %u is above 64", o->max_depth);
    return SL_OK;
}

/* ---- the cell as a sampling domain ---- */

typedef struct face {
    sl_dvec3 o, e1, e2, n;            /* point o + u e1 + v e2; n outward, unit */
    bool tri;                   /* triangle (u + v <= 1) instead of a parallelogram */
    double area;
} face;

typedef struct cellgeo {
    uint32_t shape;
    bool convex;                /* PRISM or BOX: planes, faces, vertices valid */
    int nplanes;
    double plane[6][4];         /* inside: a x + b y + c z + d >= 0, (a, b, c) unit */
    int nfaces;
    face f[6];
    double area;                /* of all faces */
    int nverts;
    sl_dvec3 v[8];
    int ndirs;
    sl_dvec3 edge_dir[4];             /* distinct edge directions (separating axes) */
    sl_dvec3 centre;
    double inset;               /* boundary origins are pulled this far inside */
    sl_aabb bounds;
    /* CLUSTER: the cluster's leaves (indices into the BSP leaves) and cumulative box volumes */
    int32_t cluster;
    uint32_t nleaves;
} cellgeo;

/* A queued (origin, newly found triangle) pair: ABS will explore around it. */
typedef struct qitem {
    double o[3];
    double hit[3];              /* where the finding ray hit the triangle: hit(x_old) for RS */
    uint32_t tri;
} qitem;

/* One ABS ray: toward `target` (a vertex of t' or a point of one of its edges). */
typedef struct sample {
    sl_dvec3 target;
    sl_dvec3 dir;                     /* target - origin */
    sl_dvec3 hit;                     /* valid when tri != SL_NONE */
    double t;                   /* hit parameter in units of dir */
    uint32_t tri;
} sample;

typedef struct segment {
    uint32_t a, b, mid;         /* sample indices */
    uint32_t depth;
} segment;

/* A half-space of a BSP leaf: the node's plane, front side (0: a x + b y + c z + d >= 0, the
 * child sl_scene_bsp_find_leaf takes for such points) or back side (1). */
typedef struct lplane {
    uint32_t plane;
    uint32_t side;
} lplane;

/* A pending reverse-sampling ray with its (double) origin. */
typedef struct rsray {
    double o[3];
    sl_es_ray ray;
} rsray;

struct sl_gvs_t {
    sl_allocator a;
    const sl_es *es;
    sl_scene scene;
    sl_gvs_options o;
    uint32_t ntri, nobj;
    double diag;                /* scene diagonal */
    double eps_world;           /* eps * diag */
    uint64_t *bits;             /* triangle found: (ntri + 63) / 64 words */
    size_t bit_words;
    uint8_t *obj_mark;          /* per object */
    sl_array found;             /* uint32 triangles, in finding order */
    sl_array tris_out, objs_out;/* uint32, ascending */
    sl_array curve;             /* uint64 pairs */
    sl_array queue;             /* qitem */
    size_t qhead;
    sl_array samples;           /* sample */
    sl_array segs, segs_next;   /* segment */
    sl_array rs;                /* rsray */
    sl_array rays;              /* sl_es_ray */
    sl_array hits;              /* sl_es_hit */
    sl_array leaves;            /* uint32: the current cluster's leaves */
    sl_array leaf_cum;          /* double: cumulative volumes */
    sl_array leaf_pfirst;       /* uint32: the leaves' ranges in leaf_planes (nleaves + 1) */
    sl_array leaf_planes;       /* lplane: the half-spaces from the root to each leaf */
    uint32_t *bsp_node_up;      /* per BSP node: parent * 2 + side, SL_NONE for the root */
    uint32_t *bsp_leaf_up;      /* per BSP leaf: parent * 2 + side, SL_NONE when unreferenced */
    uint32_t bsp_nodes, bsp_leaves;
    sl_array objs_near;         /* uint32: objects whose box meets the cell */
    cellgeo cg;
    sl_viewcells cells;
    uint32_t cell;
    sl_gvs_stats st;
    bool oom;
};

sl_status sl_gvs_create(const sl_es *es, sl_scene scene, const sl_gvs_options *opt, const sl_allocator *alloc,
                        sl_gvs *out, sl_error *err)
{
    if (!es || !scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_gvs_create: es, scene and out must not be NULL");
    *out = NULL;
    sl_gvs_options o = opt ? *opt : sl_gvs_defaults();
    sl_status st = sl_gvs_options_check(&o, err);
    if (st != SL_OK)
        return st;
    if (sl_es_object_count(es) != sl_scene_object_count(scene))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "gvs: the Embree scene has %u objects but the scene %u (built from another scene?)",
                       sl_es_object_count(es), sl_scene_object_count(scene));
    alloc = sl_alloc_or_default(alloc);
    struct sl_gvs_t *g = sl_calloc(alloc, 1, sizeof *g);
    if (!g)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory");
    g->a = *alloc;
    g->es = es;
    g->scene = scene;
    g->o = o;
    g->ntri = sl_es_triangle_count(es);
    g->nobj = sl_es_object_count(es);
    sl_aabb b = sl_es_bounds(es);
    g->diag = sl_aabb_is_empty(&b) ? 1.0
                                   : sl_d3_len(sl_d3((double)b.max.x - b.min.x, (double)b.max.y - b.min.y,
                                            (double)b.max.z - b.min.z));
    if (!(g->diag > 0))
        g->diag = 1.0;
    g->eps_world = o.eps * g->diag;
    /* BSP parent links: a cluster cell's leaves become convex regions (the half-spaces on the path
     * from the root), so that volume origins and reverse-sampling lines are tested without a
     * descent of the tree */
    sl_bsp_view bsp;
    if (sl_scene_bsp(scene, &bsp)) {
        g->bsp_nodes = bsp.node_count;
        g->bsp_leaves = bsp.leaf_count;
        g->bsp_node_up = sl_alloc(alloc, ((size_t)bsp.node_count + 1) * sizeof(uint32_t));
        g->bsp_leaf_up = sl_alloc(alloc, ((size_t)bsp.leaf_count + 1) * sizeof(uint32_t));
        if (!g->bsp_node_up || !g->bsp_leaf_up) {
            sl_gvs_destroy(g);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory for the BSP links");
        }
        for (uint32_t n = 0; n < bsp.node_count; n++)
            g->bsp_node_up[n] = SL_NONE;
        for (uint32_t l = 0; l < bsp.leaf_count; l++)
            g->bsp_leaf_up[l] = SL_NONE;
        /* the scene validated the tree: children point forward, leaves and nodes in range */
        for (uint32_t n = 0; n < bsp.node_count; n++)
            for (uint32_t side = 0; side < 2; side++) {
                int32_t c = bsp.nodes[n].children[side];
                if (c >= 0 && (uint32_t)c < bsp.node_count)
                    g->bsp_node_up[c] = 2 * n + side;
                else if (c < 0 && (uint32_t)(-(c + 1)) < bsp.leaf_count)
                    g->bsp_leaf_up[-(c + 1)] = 2 * n + side;
            }
    }
    g->bit_words = ((size_t)g->ntri + 63) / 64 + 1;
    g->bits = sl_calloc(alloc, g->bit_words, sizeof(uint64_t));
    g->obj_mark = sl_calloc(alloc, (size_t)g->nobj + 1, 1);
    if (!g->bits || !g->obj_mark) {
        sl_gvs_destroy(g);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory for %u triangles", g->ntri);
    }
    *out = g;
    return SL_OK;
}

void sl_gvs_destroy(sl_gvs g)
{
    if (!g)
        return;
    const sl_allocator *a = &g->a;
    sl_free(a, g->bits, g->bit_words * sizeof(uint64_t));
    sl_free(a, g->obj_mark, (size_t)g->nobj + 1);
    sl_array_free(a, &g->found, sizeof(uint32_t));
    sl_array_free(a, &g->tris_out, sizeof(uint32_t));
    sl_array_free(a, &g->objs_out, sizeof(uint32_t));
    sl_array_free(a, &g->curve, 2 * sizeof(uint64_t));
    sl_array_free(a, &g->queue, sizeof(qitem));
    sl_array_free(a, &g->samples, sizeof(sample));
    sl_array_free(a, &g->segs, sizeof(segment));
    sl_array_free(a, &g->segs_next, sizeof(segment));
    sl_array_free(a, &g->rs, sizeof(rsray));
    sl_array_free(a, &g->rays, sizeof(sl_es_ray));
    sl_array_free(a, &g->hits, sizeof(sl_es_hit));
    sl_array_free(a, &g->leaves, sizeof(uint32_t));
    sl_array_free(a, &g->leaf_cum, sizeof(double));
    sl_array_free(a, &g->leaf_pfirst, sizeof(uint32_t));
    sl_array_free(a, &g->leaf_planes, sizeof(lplane));
    sl_free(a, g->bsp_node_up, ((size_t)g->bsp_nodes + 1) * sizeof(uint32_t));
    sl_free(a, g->bsp_leaf_up, ((size_t)g->bsp_leaves + 1) * sizeof(uint32_t));
    sl_array_free(a, &g->objs_near, sizeof(uint32_t));
    sl_free(a, g, sizeof *g);
}

/* ---- cell setup ---- */

static void set_plane(cellgeo *c, sl_dvec3 n, sl_dvec3 p)
{
    n = sl_d3_unit(n);
    double *q = c->plane[c->nplanes++];
    q[0] = n.x, q[1] = n.y, q[2] = n.z, q[3] = -sl_d3_dot(n, p);
}

static void add_face(cellgeo *c, sl_dvec3 o, sl_dvec3 e1, sl_dvec3 e2, bool tri)
{
    face *f = &c->f[c->nfaces++];
    f->o = o, f->e1 = e1, f->e2 = e2, f->tri = tri;
    sl_dvec3 n = sl_d3_cross(e1, e2);
    f->area = sl_d3_len(n) * (tri ? 0.5 : 1.0);
    /* outward: away from the centre */
    n = sl_d3_unit(n);
    if (sl_d3_dot(n, sl_d3_sub(o, c->centre)) < 0)
        n = sl_d3_scale(n, -1);
    f->n = n;
    c->area += f->area;
}

/* Describe cell `cell` for sampling; clusters gather their leaves. */
static sl_status setup_cell(struct sl_gvs_t *g, sl_viewcells cells, uint32_t cell, sl_error *err)
{
    const sl_viewcell *vc = &sl_viewcells_data(cells)[cell];
    cellgeo *c = &g->cg;
    memset(c, 0, sizeof *c);
    c->shape = vc->shape;
    c->bounds = vc->bounds;
    c->cluster = vc->cluster;
    g->leaves.count = g->leaf_cum.count = 0;
    if (vc->shape == SL_CELL_PRISM) {
        c->convex = true;
        sl_dvec3 lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            lo[k] = sl_d3(vc->tri[k].x, vc->tri[k].y, vc->z_min);
            hi[k] = sl_d3(vc->tri[k].x, vc->tri[k].y, vc->z_max);
            c->v[k] = lo[k];
            c->v[k + 3] = hi[k];
        }
        c->nverts = 6;
        c->centre = sl_d3_scale(
            sl_d3_add(sl_d3_add(sl_d3_add(lo[0], lo[1]), sl_d3_add(lo[2], hi[0])), sl_d3_add(hi[1], hi[2])), 1.0 / 6.0);
        /* planes: bottom, top, and one per side (the triangle is counter-clockwise) */
        set_plane(c, sl_d3(0, 0, 1), lo[0]);
        set_plane(c, sl_d3(0, 0, -1), hi[0]);
        for (int k = 0; k < 3; k++) {
            sl_dvec3 e = sl_d3_sub(lo[(k + 1) % 3], lo[k]);
            set_plane(c, sl_d3(-e.y, e.x, 0), lo[k]); /* left normal of a CCW edge points inside */
            c->edge_dir[c->ndirs++] = sl_d3_unit(e);
        }
        c->edge_dir[c->ndirs++] = sl_d3(0, 0, 1);
        add_face(c, lo[0], sl_d3_sub(lo[1], lo[0]), sl_d3_sub(lo[2], lo[0]), true);
        add_face(c, hi[0], sl_d3_sub(hi[1], hi[0]), sl_d3_sub(hi[2], hi[0]), true);
        for (int k = 0; k < 3; k++)
            add_face(c, lo[k], sl_d3_sub(lo[(k + 1) % 3], lo[k]), sl_d3_sub(hi[k], lo[k]), false);
    } else if (vc->shape == SL_CELL_BOX) {
        c->convex = true;
        sl_dvec3 lo = sl_d3_of(vc->bounds.min), hi = sl_d3_of(vc->bounds.max);
        for (int i = 0; i < 8; i++)
            c->v[i] = sl_d3((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
        c->nverts = 8;
        c->centre = sl_d3_scale(sl_d3_add(lo, hi), 0.5);
        set_plane(c, sl_d3(1, 0, 0), lo);
        set_plane(c, sl_d3(-1, 0, 0), hi);
        set_plane(c, sl_d3(0, 1, 0), lo);
        set_plane(c, sl_d3(0, -1, 0), hi);
        set_plane(c, sl_d3(0, 0, 1), lo);
        set_plane(c, sl_d3(0, 0, -1), hi);
        c->edge_dir[0] = sl_d3(1, 0, 0), c->edge_dir[1] = sl_d3(0, 1, 0), c->edge_dir[2] = sl_d3(0, 0, 1);
        c->ndirs = 3;
        sl_dvec3 d = sl_d3_sub(hi, lo);
        /* a flat box (a rectangle) keeps its two large faces only: zero-area faces are never picked */
        add_face(c, lo, sl_d3(0, d.y, 0), sl_d3(0, 0, d.z), false);
        add_face(c, sl_d3(hi.x, lo.y, lo.z), sl_d3(0, d.y, 0), sl_d3(0, 0, d.z), false);
        add_face(c, lo, sl_d3(d.x, 0, 0), sl_d3(0, 0, d.z), false);
        add_face(c, sl_d3(lo.x, hi.y, lo.z), sl_d3(d.x, 0, 0), sl_d3(0, 0, d.z), false);
        add_face(c, lo, sl_d3(d.x, 0, 0), sl_d3(0, d.y, 0), false);
        add_face(c, sl_d3(lo.x, lo.y, hi.z), sl_d3(d.x, 0, 0), sl_d3(0, d.y, 0), false);
    } else {
        sl_bsp_view bsp;
        if (!sl_scene_bsp(g->scene, &bsp))
            return sl_fail(err, SL_ERROR_UNSUPPORTED, "gvs: cell %u is BSP cluster %d but the scene has no BSP data",
                           cell, (int)vc->cluster);
        double sum = 0;
        g->leaf_pfirst.count = g->leaf_planes.count = 0;
        uint32_t zero = 0;
        if (!sl_array_push(&g->a, &g->leaf_pfirst, sizeof(uint32_t), &zero, 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory for the leaves of cell %u", cell);
        for (uint32_t l = 0; l < bsp.leaf_count; l++) {
            if (bsp.leaves[l].cluster != vc->cluster)
                continue;
            const sl_aabb *b = &bsp.leaves[l].bounds;
            if (sl_aabb_is_empty(b) || (bsp.node_count > 0 && g->bsp_leaf_up[l] == SL_NONE))
                continue; /* no volume, or a leaf the tree never reaches */
            /* the half-spaces from the leaf up to the root (depth bounded by the node count) */
            uint32_t up = g->bsp_leaf_up[l];
            for (uint32_t steps = 0; up != SL_NONE && steps <= bsp.node_count; steps++) {
                lplane lp = {bsp.nodes[up / 2].plane, up % 2};
                if (!sl_array_push(&g->a, &g->leaf_planes, sizeof lp, &lp, 1))
                    return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory for the leaves of cell %u", cell);
                up = g->bsp_node_up[up / 2];
            }
            uint32_t end = (uint32_t)g->leaf_planes.count;
            sum += fmax(1e-9, ((double)b->max.x - b->min.x) * ((double)b->max.y - b->min.y) *
                                  ((double)b->max.z - b->min.z));
            if (!sl_array_push(&g->a, &g->leaves, sizeof(uint32_t), &l, 1) ||
                !sl_array_push(&g->a, &g->leaf_cum, sizeof(double), &sum, 1) ||
                !sl_array_push(&g->a, &g->leaf_pfirst, sizeof(uint32_t), &end, 1))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory for the leaves of cell %u", cell);
        }
        c->nleaves = (uint32_t)g->leaves.count;
        c->centre = sl_d3_scale(sl_d3_add(sl_d3_of(vc->bounds.min), sl_d3_of(vc->bounds.max)), 0.5);
        c->inset = 1e-3;
    }
    if (c->convex) {
        /* 1 mm inside (the region oracle's inset), at most 1% of the cell's smallest extent */
        double ex = (double)vc->bounds.max.x - vc->bounds.min.x, ey = (double)vc->bounds.max.y - vc->bounds.min.y,
               ez = (double)vc->bounds.max.z - vc->bounds.min.z;
        double m = fmin(ex, fmin(ey, ez));
        if (m <= 0)
            m = fmin(fmax(ex, ey), fmax(ey, ez));
        c->inset = fmin(1e-3, 0.01 * m);
    }
    return SL_OK;
}

/* Index of the first cumulative value above x (binary search; n > 0). */
static uint32_t pick_cum(const double *cum, uint32_t n, double x)
{
    uint32_t lo = 0, hi = n - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (cum[mid] > x)
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* A point in the cell's volume from three uniforms (and a fourth for the leaf of a cluster);
 * false when a cluster point falls outside the cluster (solid space, another cluster). */
static bool volume_point(struct sl_gvs_t *g, const double *u4, sl_dvec3 *out)
{
    const cellgeo *c = &g->cg;
    if (c->shape == SL_CELL_PRISM) {
        double a = u4[1], b = u4[2];
        if (a + b > 1)
            a = 1 - a, b = 1 - b;
        sl_dvec3 p = sl_d3_add(c->v[0], sl_d3_add(sl_d3_scale(sl_d3_sub(c->v[1], c->v[0]), a),
                                                  sl_d3_scale(sl_d3_sub(c->v[2], c->v[0]), b)));
        p.z = c->v[0].z + u4[3] * (c->v[3].z - c->v[0].z);
        *out = p;
        return true;
    }
    if (c->shape == SL_CELL_BOX) {
        const sl_aabb *b = &c->bounds;
        *out = sl_d3(b->min.x + u4[1] * ((double)b->max.x - b->min.x), b->min.y + u4[2] * ((double)b->max.y - b->min.y),
                  b->min.z + u4[3] * ((double)b->max.z - b->min.z));
        return true;
    }
    if (c->nleaves == 0)
        return false;
    const double *cum = g->leaf_cum.data;
    uint32_t k = pick_cum(cum, c->nleaves, u4[0] * cum[c->nleaves - 1]);
    sl_bsp_view bsp;
    sl_scene_bsp(g->scene, &bsp);
    const sl_aabb *b = &bsp.leaves[SL_AT(g->leaves, uint32_t, k)].bounds;
    sl_vec3 p = {(float)(b->min.x + u4[1] * ((double)b->max.x - b->min.x)),
                 (float)(b->min.y + u4[2] * ((double)b->max.y - b->min.y)),
                 (float)(b->min.z + u4[3] * ((double)b->max.z - b->min.z))};
    *out = sl_d3_of(p);
    /* in the leaf: the same float test as the tree's descent (sl_scene_bsp_find_leaf), so a point
     * accepted here is one the BSP puts in this leaf */
    const uint32_t *pf = g->leaf_pfirst.data;
    const lplane *lp = g->leaf_planes.data;
    for (uint32_t i = pf[k]; i < pf[k + 1]; i++) {
        const sl_plane *pl = &bsp.planes[lp[i].plane];
        float d = pl->a * p.x + pl->b * p.y + pl->c * p.z + pl->d;
        if ((d >= 0) != (lp[i].side == 0))
            return false;
    }
    return true;
}

bool sl_gvs_cell_point(sl_gvs g, sl_viewcells cells, uint32_t cell, const double *u, uint32_t tries, sl_vec3 *out)
{
    if (!g || !cells || !u || !out || cell >= sl_viewcells_count(cells))
        return false;
    g->cells = cells;
    g->cell = cell;
    if (setup_cell(g, cells, cell, NULL) != SL_OK)
        return false;
    for (uint32_t i = 0; i < tries; i++) {
        sl_dvec3 p;
        if (volume_point(g, u + 4 * (size_t)i, &p)) {
            *out = (sl_vec3){(float)p.x, (float)p.y, (float)p.z};
            return true;
        }
    }
    return false;
}

/* ---- triangles meeting a convex cell (visible by definition, section 5.3) ---- */

static void project(const sl_dvec3 *p, int n, sl_dvec3 axis, double *lo, double *hi)
{
    *lo = INFINITY, *hi = -INFINITY;
    for (int i = 0; i < n; i++) {
        double d = sl_d3_dot(p[i], axis);
        *lo = fmin(*lo, d), *hi = fmax(*hi, d);
    }
}

/* Separating-axis test of a triangle against the convex cell (closed: touching meets). */
static bool tri_meets_cell(const cellgeo *c, const sl_dvec3 t[3])
{
    sl_dvec3 axes[6 + 1 + 12];
    int na = 0;
    for (int k = 0; k < c->nplanes; k++)
        axes[na++] = sl_d3(c->plane[k][0], c->plane[k][1], c->plane[k][2]);
    sl_dvec3 e[3] = {sl_d3_sub(t[1], t[0]), sl_d3_sub(t[2], t[1]), sl_d3_sub(t[0], t[2])};
    axes[na++] = sl_d3_cross(e[0], e[1]);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < c->ndirs; j++)
            axes[na++] = sl_d3_cross(e[i], c->edge_dir[j]);
    for (int k = 0; k < na; k++) {
        double l = sl_d3_len(axes[k]);
        if (!(l > 1e-12))
            continue;
        sl_dvec3 ax = sl_d3_scale(axes[k], 1.0 / l);
        double a0, a1, b0, b1;
        project(t, 3, ax, &a0, &a1);
        project(c->v, c->nverts, ax, &b0, &b1);
        double tol = 1e-9 * (1.0 + fabs(a0) + fabs(b0));
        if (a1 < b0 - tol || b1 < a0 - tol)
            return false;
    }
    return true;
}

/* ---- the sampler ---- */

static inline bool bit_get(const struct sl_gvs_t *g, uint32_t t) { return (g->bits[t >> 6] >> (t & 63)) & 1u; }
static inline void bit_set(struct sl_gvs_t *g, uint32_t t) { g->bits[t >> 6] |= 1ull << (t & 63); }

/* Record a triangle; true when it is new. */
static bool mark(struct sl_gvs_t *g, uint32_t tri)
{
    if (bit_get(g, tri))
        return false;
    bit_set(g, tri);
    if (!sl_array_push(&g->a, &g->found, sizeof tri, &tri, 1))
        g->oom = true;
    return true;
}

/* handle_ray of the paper: a new triangle joins the PVS and, for GVS, the ABS queue. */
static void handle(struct sl_gvs_t *g, sl_dvec3 o, sl_dvec3 dir, const sl_es_hit *h)
{
    /* a see-through surface the ray passed through is seen (found), but sampling goes on from the
     * solid hit behind it */
    if (h->see_through_triangle != SL_NONE)
        mark(g, h->see_through_triangle);
    if (h->triangle == SL_NONE || !mark(g, h->triangle))
        return;
    if (g->o.sampler != SL_GVS_GUIDED)
        return;
    qitem q;
    q.o[0] = o.x, q.o[1] = o.y, q.o[2] = o.z;
    sl_dvec3 p = sl_d3_add(o, sl_d3_scale(dir, h->t));
    q.hit[0] = p.x, q.hit[1] = p.y, q.hit[2] = p.z;
    q.tri = h->triangle;
    if (!sl_array_push(&g->a, &g->queue, sizeof q, &q, 1))
        g->oom = true;
}

static sl_es_ray make_ray(sl_dvec3 o, sl_dvec3 d)
{
    sl_es_ray r;
    r.org[0] = (float)o.x, r.org[1] = (float)o.y, r.org[2] = (float)o.z;
    r.dir[0] = (float)d.x, r.dir[1] = (float)d.y, r.dir[2] = (float)d.z;
    r.tnear = 0.0f;
    r.tfar = INFINITY;
    return r;
}

/* Room for n rays and hits in the scratch arrays. */
static bool reserve_rays(struct sl_gvs_t *g, size_t n)
{
    g->rays.count = g->hits.count = 0;
    if (!sl_array_reserve(&g->a, &g->rays, sizeof(sl_es_ray), n) ||
        !sl_array_reserve(&g->a, &g->hits, sizeof(sl_es_hit), n)) {
        g->oom = true;
        return false;
    }
    return true;
}

/* One random ray (section 5.3.1). False when a volume origin missed the cluster (drawn again). */
static bool random_ray(struct sl_gvs_t *g, const double *x, bool boundary, sl_dvec3 *o, sl_dvec3 *d)
{
    const cellgeo *c = &g->cg;
    if (boundary) {
        /* x0 picks the face by area, (x1, x2) = (u, v), phi = 2 pi x3, sin(theta) = x4 */
        double pick = x[0] * c->area;
        int k = 0;
        while (k < c->nfaces - 1 && pick >= c->f[k].area) {
            pick -= c->f[k].area;
            k++;
        }
        while (k > 0 && !(c->f[k].area > 0)) /* rounding left the pick on a flat box's empty face */
            k--;
        const face *f = &c->f[k];
        double u = x[1], v = x[2];
        if (f->tri && u + v > 1)
            u = 1 - u, v = 1 - v;
        sl_dvec3 p = sl_d3_add(f->o, sl_d3_add(sl_d3_scale(f->e1, u), sl_d3_scale(f->e2, v)));
        sl_dvec3 to_c = sl_d3_sub(c->centre, p);
        double lc = sl_d3_len(to_c);
        if (lc > 0)
            p = sl_d3_add(p, sl_d3_scale(to_c, fmin(c->inset, lc) / lc));
        sl_dvec3 t1 = sl_d3_unit(f->e1), t2 = sl_d3_cross(f->n, t1);
        double phi = 2.0 * M_PI * x[3], st = x[4], ct = sqrt(fmax(0.0, 1.0 - st * st));
        *o = p;
        *d = sl_d3_add(sl_d3_scale(sl_d3_add(sl_d3_scale(t1, cos(phi)), sl_d3_scale(t2, sin(phi))), ct),
                       sl_d3_scale(f->n, st));
        return true;
    }
    sl_dvec3 p;
    if (!volume_point(g, x, &p))
        return false;
    /* uniform over the sphere: z = 2 x4 - 1, phi = 2 pi x5 */
    double z = 2.0 * x[4] - 1.0, r = sqrt(fmax(0.0, 1.0 - z * z)), phi = 2.0 * M_PI * x[5];
    *o = p;
    *d = sl_d3(r * cos(phi), r * sin(phi), z);
    return true;
}

/* Smallest s >= 1 (at most smax) with L(s) = x + s (p - x) in the cell, pulled inside by the
 * inset; false when the line beyond p misses the cell (the mutated ray is not in the ray set). */
static bool line_cell(struct sl_gvs_t *g, sl_dvec3 x, sl_dvec3 p, double smax, sl_dvec3 *out)
{
    const cellgeo *c = &g->cg;
    sl_dvec3 d = sl_d3_sub(p, x);
    double dl = sl_d3_len(d);
    if (!(dl > 0))
        return false;
    if (c->convex) {
        double lo = 1.0, hi = smax;
        for (int k = 0; k < c->nplanes && lo <= hi; k++) {
            const double *q = c->plane[k];
            double f0 = q[0] * x.x + q[1] * x.y + q[2] * x.z + q[3];
            double fd = q[0] * d.x + q[1] * d.y + q[2] * d.z;
            /* f0 + s fd >= 0 */
            if (fabs(fd) < 1e-300) {
                if (f0 < 0)
                    return false;
            } else if (fd > 0) {
                lo = fmax(lo, -f0 / fd);
            } else {
                hi = fmin(hi, -f0 / fd);
            }
        }
        if (!(lo <= hi))
            return false;
        double s = fmin(lo + c->inset / dl, hi);
        *out = sl_d3_add(x, sl_d3_scale(d, s));
        return true;
    }
    /* cluster: clip against each leaf (its box and its half-spaces), keep the nearest entry */
    sl_bsp_view bsp;
    sl_scene_bsp(g->scene, &bsp);
    const uint32_t *pf = g->leaf_pfirst.data;
    const lplane *lps = g->leaf_planes.data;
    double best = INFINITY, best_hi = INFINITY;
    for (uint32_t k = 0; k < c->nleaves; k++) {
        const sl_aabb *b = &bsp.leaves[SL_AT(g->leaves, uint32_t, k)].bounds;
        double lo = 1.0, hi = smax;
        const double xo[3] = {x.x, x.y, x.z}, dd[3] = {d.x, d.y, d.z};
        const double bl[3] = {b->min.x, b->min.y, b->min.z}, bh[3] = {b->max.x, b->max.y, b->max.z};
        for (int a = 0; a < 3 && lo <= hi; a++) {
            if (fabs(dd[a]) < 1e-300) {
                if (xo[a] < bl[a] || xo[a] > bh[a])
                    lo = INFINITY;
                continue;
            }
            double s0 = (bl[a] - xo[a]) / dd[a], s1 = (bh[a] - xo[a]) / dd[a];
            if (s0 > s1) {
                double t = s0;
                s0 = s1, s1 = t;
            }
            lo = fmax(lo, s0), hi = fmin(hi, s1);
        }
        for (uint32_t i = pf[k]; i < pf[k + 1] && lo <= hi; i++) {
            const sl_plane *pl = &bsp.planes[lps[i].plane];
            double sg = lps[i].side == 0 ? 1.0 : -1.0;
            double f0 = sg * ((double)pl->a * x.x + (double)pl->b * x.y + (double)pl->c * x.z + pl->d);
            double fd = sg * ((double)pl->a * d.x + (double)pl->b * d.y + (double)pl->c * d.z);
            if (fabs(fd) < 1e-300) {
                if (f0 < 0)
                    lo = INFINITY;
            } else if (fd > 0) {
                lo = fmax(lo, -f0 / fd);
            } else {
                hi = fmin(hi, -f0 / fd);
            }
        }
        if (lo <= hi && lo < best) {
            best = lo;
            best_hi = hi;
        }
    }
    if (!isfinite(best))
        return false;
    *out = sl_d3_add(x, sl_d3_scale(d, best + fmin(c->inset / dl, 0.5 * (best_hi - best))));
    return true;
}

/* Reverse sampling (section 5.3.3) for ABS sample s of queue item q (triangle t with vertices
 * tv): when s hit a triangle clearly in front of t's plane, queue a ray from elsewhere in the
 * cell that passes just beside that occluder toward the point of t's plane that s was aimed at. */
static void check_discontinuity(struct sl_gvs_t *g, const qitem *q, const sl_dvec3 tv[3], sl_dvec3 tn, const sample *s)
{
    if (s->tri == SL_NONE || s->tri == q->tri)
        return;
    sl_dvec3 o = sl_d3_of_array(q->o);
    double den = sl_d3_dot(tn, s->dir);
    if (fabs(den) < 1e-300)
        return;
    double tp = sl_d3_dot(tn, sl_d3_sub(tv[0], o)) / den; /* predicted(x) = o + tp dir */
    if (!(tp > 0) || !isfinite(tp))
        return;
    double dl = sl_d3_len(s->dir);
    double gap = (tp - s->t) * dl;
    if (!(gap > g->o.rs_delta * tp * dl) || !(gap > g->eps_world))
        return;
    g->st.reverse_tries++;
    sl_dvec3 x = sl_d3_add(o, sl_d3_scale(s->dir, tp));
    /* the plane through the origin, hit(x) and hit(x_old) */
    sl_dvec3 m = sl_d3_cross(sl_d3_sub(s->hit, o), sl_d3_sub(sl_d3_of_array(q->hit), o));
    double ml = sl_d3_len(m);
    if (!(ml > 1e-300)) {
        g->st.reverse_missed++;
        return;
    }
    m = sl_d3_scale(m, 1.0 / ml);
    double ov[3][3];
    sl_es_triangle_vertices(g->es, s->tri, ov);
    sl_dvec3 w[3] = {sl_d3_of_array(ov[0]), sl_d3_of_array(ov[1]), sl_d3_of_array(ov[2])};
    double sd[3];
    for (int k = 0; k < 3; k++)
        sd[k] = sl_d3_dot(m, sl_d3_sub(w[k], o));
    sl_dvec3 ends[2];
    int ne = 0;
    for (int k = 0; k < 3 && ne < 2; k++) {
        int j = (k + 1) % 3;
        if (sd[k] == 0) {
            ends[ne++] = w[k];
        } else if ((sd[k] < 0) != (sd[j] < 0) && sd[j] != 0) {
            double f = sd[k] / (sd[k] - sd[j]);
            ends[ne++] = sl_d3_add(w[k], sl_d3_scale(sl_d3_sub(w[j], w[k]), f));
        }
    }
    if (ne < 2 || !(sl_d3_len(sl_d3_sub(ends[0], ends[1])) > 0)) {
        g->st.reverse_missed++;
        return;
    }
    /* the end nearer to hit(x) first; the other when the first line misses the cell */
    if (sl_d3_len(sl_d3_sub(ends[1], s->hit)) < sl_d3_len(sl_d3_sub(ends[0], s->hit))) {
        sl_dvec3 t = ends[0];
        ends[0] = ends[1], ends[1] = t;
    }
    for (int e = 0; e < 2; e++) {
        sl_dvec3 end = ends[e], away = sl_d3_unit(sl_d3_sub(end, ends[1 - e]));
        sl_dvec3 pnew = sl_d3_add(end, sl_d3_scale(away, g->o.eps * sl_d3_len(sl_d3_sub(end, x)) + 1e-9 * g->diag));
        sl_dvec3 org;
        /* the origin may lie up to twice the scene's diagonal behind p_new (s is in units of
         * |p_new - predicted|) */
        double seg = sl_d3_len(sl_d3_sub(pnew, x));
        if (!(seg > 0) || !line_cell(g, x, pnew, 1.0 + 2.0 * g->diag / seg, &org))
            continue;
        rsray r;
        r.o[0] = org.x, r.o[1] = org.y, r.o[2] = org.z;
        r.ray = make_ray(org, sl_d3_sub(x, org));
        if (!sl_array_push(&g->a, &g->rs, sizeof r, &r, 1))
            g->oom = true;
        return;
    }
    g->st.reverse_missed++;
}

/* Trace the pending reverse-sampling rays and handle them (new triangles are explored from the
 * new origins). */
static void flush_reverse(struct sl_gvs_t *g)
{
    size_t n = g->rs.count;
    if (n == 0 || !reserve_rays(g, n))
        return;
    rsray *r = g->rs.data;
    sl_es_ray *rays = g->rays.data;
    sl_es_hit *hits = g->hits.data;
    for (size_t i = 0; i < n; i++)
        rays[i] = r[i].ray;
    sl_es_trace(g->es, rays, hits, (uint32_t)n);
    g->st.rays += n;
    g->st.reverse_rays += n;
    for (size_t i = 0; i < n; i++)
        handle(g, sl_d3_of_array(r[i].o), sl_d3(r[i].ray.dir[0], r[i].ray.dir[1], r[i].ray.dir[2]), &hits[i]);
    g->rs.count = 0;
}

/* Trace samples [first, first + n) from origin o and handle them. */
static void trace_samples(struct sl_gvs_t *g, const qitem *q, const sl_dvec3 tv[3], sl_dvec3 tn, size_t first, size_t n)
{
    if (!reserve_rays(g, n))
        return;
    sl_dvec3 o = sl_d3_of_array(q->o);
    sample *s = (sample *)g->samples.data + first;
    sl_es_ray *rays = g->rays.data;
    sl_es_hit *hits = g->hits.data;
    for (size_t i = 0; i < n; i++)
        rays[i] = make_ray(o, s[i].dir);
    sl_es_trace(g->es, rays, hits, (uint32_t)n);
    g->st.rays += n;
    g->st.border_rays += n;
    for (size_t i = 0; i < n; i++) {
        s[i].tri = hits[i].triangle;
        s[i].t = hits[i].t;
        if (s[i].tri != SL_NONE)
            s[i].hit = sl_d3_add(o, sl_d3_scale(s[i].dir, s[i].t));
        handle(g, o, s[i].dir, &hits[i]);
        check_discontinuity(g, q, tv, tn, &s[i]);
    }
    flush_reverse(g);
}

/* Does the edge between samples a and b need a ray in between (subdiv_edge of section 5.3.4)? */
static bool needs_split(const struct sl_gvs_t *g, const sample *a, const sample *b, uint32_t depth)
{
    if (a->tri == b->tri || depth >= g->o.max_depth)
        return false;
    if (a->tri != SL_NONE && b->tri != SL_NONE && sl_d3_len(sl_d3_sub(a->hit, b->hit)) < g->eps_world)
        return false;
    /* rays closer than eps in angle: the enlargement's own resolution, nothing finer is sought */
    double la = sl_d3_len(a->dir), lb = sl_d3_len(b->dir);
    return sl_d3_len(sl_d3_sub(sl_d3_scale(a->dir, 1.0 / la), sl_d3_scale(b->dir, 1.0 / lb))) >= g->o.eps;
}

static bool push_sample(struct sl_gvs_t *g, sl_dvec3 o, sl_dvec3 target)
{
    sample s;
    memset(&s, 0, sizeof s);
    s.target = target;
    s.dir = sl_d3_sub(target, o);
    s.tri = SL_NONE;
    if (!(sl_d3_len(s.dir) > 0)) /* the origin lies on t' (a triangle through the cell): nudge */
        s.dir = sl_d3(0, 0, 1e-9);
    if (!sl_array_push(&g->a, &g->samples, sizeof s, &s, 1)) {
        g->oom = true;
        return false;
    }
    return true;
}

/* The enlarged polygon t' of triangle p seen from o (section 5.3.2): three vertices per corner,
 * on d_{i,i-1}, d_{i,i} and d_{i,i+1}, eps * |p_i - o| from p_i and perpendicular to the ray to
 * p_i, in order around the triangle. Each d is flipped when it points into the triangle: the paper
 * inverts them for back faces, and testing against the opposite vertex does that and also fixes
 * the sign of the bisector's fallback formula (used when the corner is sharper than 90 degrees). */
static void enlarge(sl_dvec3 o, const sl_dvec3 p[3], double eps, sl_dvec3 out[9])
{
    sl_dvec3 centroid = sl_d3_scale(sl_d3_add(sl_d3_add(p[0], p[1]), p[2]), 1.0 / 3.0);
    for (int i = 0; i < 3; i++) {
        sl_dvec3 pi = p[i], prev = p[(i + 2) % 3], next = p[(i + 1) % 3];
        sl_dvec3 v = sl_d3_sub(pi, o);
        sl_dvec3 dn = sl_d3_unit(sl_d3_cross(v, sl_d3_sub(next, pi)));
        if (sl_d3_dot(dn, sl_d3_sub(prev, pi)) > 0)
            dn = sl_d3_scale(dn, -1);
        sl_dvec3 dp = sl_d3_unit(sl_d3_cross(v, sl_d3_sub(pi, prev)));
        if (sl_d3_dot(dp, sl_d3_sub(next, pi)) > 0)
            dp = sl_d3_scale(dp, -1);
        sl_dvec3 dm =
            sl_d3_dot(dp, dn) > 0 ? sl_d3_unit(sl_d3_add(dp, dn)) : sl_d3_unit(sl_d3_cross(v, sl_d3_sub(dp, dn)));
        if (sl_d3_dot(dm, sl_d3_sub(pi, centroid)) < 0)
            dm = sl_d3_scale(dm, -1);
        double r = eps * sl_d3_len(v);
        out[3 * i] = sl_d3_add(pi, sl_d3_scale(dp, r));
        out[3 * i + 1] = sl_d3_add(pi, sl_d3_scale(dm, r));
        out[3 * i + 2] = sl_d3_add(pi, sl_d3_scale(dn, r));
    }
}

void sl_gvs_enlarge(const double o[3], const double *tri, double eps, double *out)
{
    sl_dvec3 p[3] = {sl_d3_of_array(tri), sl_d3_of_array(tri + 3), sl_d3_of_array(tri + 6)}, r[9];
    enlarge(sl_d3_of_array(o), p, eps, r);
    for (int k = 0; k < 9; k++)
        out[3 * k] = r[k].x, out[3 * k + 1] = r[k].y, out[3 * k + 2] = r[k].z;
}

/* Adaptive border sampling around queue item q (section 5.3.2). */
static void border_sampling(struct sl_gvs_t *g, const qitem *q)
{
    double tvd[3][3];
    sl_es_triangle_vertices(g->es, q->tri, tvd);
    sl_dvec3 p[3] = {sl_d3_of_array(tvd[0]), sl_d3_of_array(tvd[1]), sl_d3_of_array(tvd[2])};
    sl_dvec3 o = sl_d3_of_array(q->o);
    sl_dvec3 tn = sl_d3_cross(sl_d3_sub(p[1], p[0]), sl_d3_sub(p[2], p[0]));

    sl_dvec3 ring[9];
    enlarge(o, p, g->o.eps, ring);
    g->samples.count = 0;
    for (int k = 0; k < 9; k++)
        push_sample(g, o, ring[k]);
    if (g->oom)
        return;
    trace_samples(g, q, p, tn, 0, 9);

    /* subdivide the 9 edges of t' level by level: every level's midpoints are traced together */
    g->segs.count = 0;
    for (uint32_t k = 0; k < 9; k++) {
        const sample *s = g->samples.data;
        if (needs_split(g, &s[k], &s[(k + 1) % 9], 0)) {
            segment e = {k, (k + 1) % 9, 0, 0};
            if (!sl_array_push(&g->a, &g->segs, sizeof e, &e, 1))
                g->oom = true;
        }
    }
    while (g->segs.count && !g->oom && g->st.rays < g->o.max_rays) {
        size_t first = g->samples.count, n = g->segs.count;
        for (size_t i = 0; i < n; i++) {
            segment *e = &SL_AT(g->segs, segment, i);
            const sample *s = g->samples.data;
            sl_dvec3 mid = sl_d3_scale(sl_d3_add(s[e->a].target, s[e->b].target), 0.5);
            e->mid = (uint32_t)g->samples.count;
            if (!push_sample(g, o, mid))
                return;
        }
        trace_samples(g, q, p, tn, first, n);
        g->segs_next.count = 0;
        for (size_t i = 0; i < n && !g->oom; i++) {
            segment e = SL_AT(g->segs, segment, i);
            const sample *s = g->samples.data;
            segment l = {e.a, e.mid, 0, e.depth + 1}, r = {e.mid, e.b, 0, e.depth + 1};
            if (needs_split(g, &s[l.a], &s[l.b], l.depth) && !sl_array_push(&g->a, &g->segs_next, sizeof l, &l, 1))
                g->oom = true;
            if (needs_split(g, &s[r.a], &s[r.b], r.depth) && !sl_array_push(&g->a, &g->segs_next, sizeof r, &r, 1))
                g->oom = true;
        }
        sl_array t = g->segs;
        g->segs = g->segs_next;
        g->segs_next = t;
    }
}

/* Triangles meeting a convex cell are visible by definition (section 5.3). */
static void auto_visible(struct sl_gvs_t *g)
{
    const cellgeo *c = &g->cg;
    const sl_aabb *ob = sl_scene_object_bounds_array(g->scene);
    const sl_aabb *cb = &c->bounds;
    for (uint32_t i = 0; i < g->nobj && !g->oom; i++) {
        const sl_aabb *b = &ob[i];
        if (b->min.x > cb->max.x || b->max.x < cb->min.x || b->min.y > cb->max.y || b->max.y < cb->min.y ||
            b->min.z > cb->max.z || b->max.z < cb->min.z)
            continue;
        uint32_t t0 = sl_es_object_first_triangle(g->es, i), t1 = sl_es_object_first_triangle(g->es, i + 1);
        for (uint32_t t = t0; t < t1; t++) {
            double tv[3][3];
            sl_es_triangle_vertices(g->es, t, tv);
            sl_dvec3 w[3] = {sl_d3_of_array(tv[0]), sl_d3_of_array(tv[1]), sl_d3_of_array(tv[2])};
            if (tri_meets_cell(c, w) && mark(g, t))
                g->st.auto_visible++;
        }
    }
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Clear the per-cell marks (only the bits that were set: the cost follows the set, not the scene). */
static void reset_marks(struct sl_gvs_t *g)
{
    const uint32_t *f = g->found.data;
    for (size_t i = 0; i < g->found.count; i++)
        g->bits[f[i] >> 6] = 0;
    const uint32_t *ob = g->objs_out.data;
    for (size_t i = 0; i < g->objs_out.count; i++)
        g->obj_mark[ob[i]] = 0;
    g->found.count = g->tris_out.count = g->objs_out.count = g->curve.count = 0;
    g->queue.count = g->qhead = 0;
    g->rs.count = 0;
}

sl_status sl_gvs_cell(sl_gvs g, sl_viewcells cells, uint32_t cell, sl_gvs_result *out, sl_error *err)
{
    if (!g || !cells || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_gvs_cell: arguments must not be NULL");
    memset(out, 0, sizeof *out);
    if (cell >= sl_viewcells_count(cells))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: cell %u does not exist (%u cells)", cell,
                       sl_viewcells_count(cells));
    double t0 = sl_now();
    reset_marks(g);
    memset(&g->st, 0, sizeof g->st);
    g->oom = false;
    g->cells = cells;
    g->cell = cell;
    sl_status st = setup_cell(g, cells, cell, err);
    if (st != SL_OK)
        return st;
    const cellgeo *c = &g->cg;
    uint32_t origins = g->o.origins;
    if (origins == SL_GVS_ORIGINS_AUTO)
        origins = c->convex ? SL_GVS_ORIGINS_BOUNDARY : SL_GVS_ORIGINS_VOLUME;
    if (origins == SL_GVS_ORIGINS_BOUNDARY && !c->convex)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "gvs: cell %u is a BSP cluster, which has no boundary faces to sample; use volume origins", cell);
    const bool boundary = origins == SL_GVS_ORIGINS_BOUNDARY;
    if (boundary && !(c->area > 0))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "gvs: cell %u has no boundary area", cell);

    if (c->convex && g->o.auto_visible)
        auto_visible(g);

    sl_halton h;
    sl_halton_init(&h, 6, true, g->o.seed, cell);
    const uint64_t window = g->o.window, max_rays = g->o.max_rays;
    uint64_t window_start = 0, window_found = g->found.count;
    uint32_t rejects_in_row = 0;
    g->st.stop = SL_GVS_STOP_MAX_RAYS;
    if (!c->convex && c->nleaves == 0)
        g->st.stop = SL_GVS_STOP_NO_RAYS;
    while (!g->oom && g->st.stop != SL_GVS_STOP_NO_RAYS) {
        if (g->st.rays >= max_rays) {
            g->st.stop = SL_GVS_STOP_MAX_RAYS;
            break;
        }
        if (g->st.rays - window_start >= window) {
            /* section 5.3.5: at most min_new new triangles per window (scaled when the check comes
             * late because an ABS burst ran past the window's end) */
            uint64_t elapsed = g->st.rays - window_start, fresh = g->found.count - window_found;
            if (g->o.log_curve) {
                uint64_t pt[2] = {g->st.rays, g->found.count};
                if (!sl_array_push(&g->a, &g->curve, sizeof pt, pt, 1))
                    g->oom = true;
            }
            if ((double)fresh * (double)window <= (double)g->o.min_new * (double)elapsed) {
                g->st.stop = SL_GVS_STOP_CONVERGED;
                break;
            }
            window_start = g->st.rays;
            window_found = g->found.count;
        }
        uint32_t n = (uint32_t)SL_MIN((uint64_t)g->o.batch, max_rays - g->st.rays);
        if (!reserve_rays(g, n))
            break;
        sl_es_ray *rays = g->rays.data;
        /* the origins in double, for the queue: the RS scratch is free between ABS runs */
        g->rs.count = 0;
        if (!sl_array_reserve(&g->a, &g->rs, sizeof(rsray), n)) {
            g->oom = true;
            break;
        }
        rsray *ro = g->rs.data;
        uint32_t made = 0;
        while (made < n) {
            double x[6];
            sl_halton_next(&h, x);
            sl_dvec3 o, d;
            if (!random_ray(g, x, boundary, &o, &d)) {
                g->st.origin_rejects++;
                /* a cluster whose leaf boxes are (nearly) all solid: give up rather than spin */
                if (++rejects_in_row > 100000) {
                    g->st.stop = SL_GVS_STOP_NO_RAYS;
                    break;
                }
                continue;
            }
            rejects_in_row = 0;
            ro[made].o[0] = o.x, ro[made].o[1] = o.y, ro[made].o[2] = o.z;
            rays[made] = make_ray(o, d);
            made++;
        }
        if (made == 0)
            break;
        sl_es_trace(g->es, rays, g->hits.data, made);
        g->st.rays += made;
        g->st.random_rays += made;
        const sl_es_hit *hits = g->hits.data;
        for (uint32_t i = 0; i < made; i++)
            handle(g, sl_d3_of_array(ro[i].o), sl_d3(rays[i].dir[0], rays[i].dir[1], rays[i].dir[2]), &hits[i]);
        g->rs.count = 0;
        if (g->o.sampler == SL_GVS_GUIDED && g->st.random_rays >= g->o.initial) {
            /* drain the queue: ABS around every new triangle, from the origin that found it */
            while (g->qhead < g->queue.count && !g->oom && g->st.rays < max_rays) {
                qitem q = SL_AT(g->queue, qitem, g->qhead);
                g->qhead++;
                border_sampling(g, &q);
            }
            if (g->qhead >= g->queue.count)
                g->queue.count = g->qhead = 0;
        }
    }
    if (g->oom)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory in cell %u after %llu rays", cell,
                       (unsigned long long)g->st.rays);
    if (g->o.log_curve) {
        uint64_t pt[2] = {g->st.rays, g->found.count};
        if (!sl_array_push(&g->a, &g->curve, sizeof pt, pt, 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory");
    }

    /* results: triangles ascending, and the objects that own them */
    size_t nf = g->found.count;
    if (!sl_array_reserve(&g->a, &g->tris_out, sizeof(uint32_t), nf + 1) ||
        !sl_array_reserve(&g->a, &g->objs_out, sizeof(uint32_t), nf + 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory for %zu triangles", nf);
    if (nf)
        memcpy(g->tris_out.data, g->found.data, nf * sizeof(uint32_t));
    g->tris_out.count = nf;
    qsort(g->tris_out.data, nf, sizeof(uint32_t), cmp_u32);
    const uint32_t *tr = g->tris_out.data;
    uint32_t *ob = g->objs_out.data;
    for (size_t i = 0; i < nf; i++) {
        uint32_t obj = sl_es_triangle_object(g->es, tr[i]);
        if (!g->obj_mark[obj]) {
            g->obj_mark[obj] = 1;
            ob[g->objs_out.count++] = obj; /* ascending: triangles are numbered object by object */
        }
    }
    g->st.triangles = (uint32_t)nf;
    g->st.objects = (uint32_t)g->objs_out.count;
    g->st.seconds = sl_now() - t0;
    out->triangles = g->tris_out.data;
    out->triangle_count = (uint32_t)nf;
    out->objects = g->objs_out.data;
    out->object_count = (uint32_t)g->objs_out.count;
    out->curve = g->curve.data;
    out->curve_count = (uint32_t)g->curve.count;
    out->stats = g->st;
    return SL_OK;
}

/* ==== the `gvs` PVS method (pvs_internal.h) ================================================== */

typedef struct gvs_config {
    sl_gvs_options o;
} gvs_config;

typedef struct gvs_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    sl_es *es;
    sl_gvs_options o;
} gvs_shared;

static const char g_gvs_help[] =
    "sampler=gvs|random (default gvs): guided sampling (random rays + adaptive border sampling + reverse sampling), "
    "or the plain random-sampling baseline\n"
    "origins=auto|boundary|volume (default auto): ray origins on the cell's faces (prism, box) or inside it "
    "(auto: boundary for prisms and boxes, volume for BSP clusters)\n"
    "eps=FLOAT (default 5e-05): relative enlargement of ABS polygons (radians) and smallest ABS ray spacing; "
    "eps * scene diagonal is the world distance at which hits count as adjacent\n"
    "delta=FLOAT (default 0.01): reverse sampling fires when a ray hits closer than the original triangle's plane by "
    "more than delta times that plane's distance\n"
    "window=INT (default 1000000): rays per termination window\n"
    "min_new=INT (default 50): stop when a window finds at most this many new triangles\n"
    "max_rays=INT (default 10000000): ray budget per cell\n"
    "initial=INT (default 0): random rays cast before adaptive border sampling starts (progressive variant)\n"
    "auto_visible=BOOL (default true): triangles meeting a prism or box cell are visible by definition\n"
    "seed=INT (default 0): rotates the Halton sequences (with the cell index)\n";

static sl_status gvs_configure(sl_opts *op, void *config, sl_error *err)
{
    gvs_config *c = config;
    c->o = sl_gvs_defaults();
    static const char *const samplers[] = {"gvs", "random"};
    static const char *const origins[] = {"auto", "boundary", "volume"};
    uint32_t window, min_new, max_rays, initial, seed;
    float eps, delta;
    sl_status st;
    if ((st = sl_opts_enum(op, "sampler", samplers, 2, 0, &c->o.sampler, err)) != SL_OK ||
        (st = sl_opts_enum(op, "origins", origins, 3, 0, &c->o.origins, err)) != SL_OK ||
        (st = sl_opts_float(op, "eps", 5e-5f, 1e-9f, 0.1f, &eps, err)) != SL_OK ||
        (st = sl_opts_float(op, "delta", 0.01f, 0.0f, 100.0f, &delta, err)) != SL_OK ||
        (st = sl_opts_u32(op, "window", 1000000u, 1u, UINT32_MAX, &window, err)) != SL_OK ||
        (st = sl_opts_u32(op, "min_new", 50u, 0u, UINT32_MAX, &min_new, err)) != SL_OK ||
        (st = sl_opts_u32(op, "max_rays", 10000000u, 1u, UINT32_MAX, &max_rays, err)) != SL_OK ||
        (st = sl_opts_u32(op, "initial", 0u, 0u, UINT32_MAX, &initial, err)) != SL_OK ||
        (st = sl_opts_bool(op, "auto_visible", true, &c->o.auto_visible, err)) != SL_OK ||
        (st = sl_opts_u32(op, "seed", 0u, 0u, UINT32_MAX, &seed, err)) != SL_OK)
        return st;
    c->o.eps = eps;
    c->o.rs_delta = delta;
    c->o.window = window;
    c->o.min_new = min_new;
    c->o.max_rays = max_rays;
    c->o.initial = initial;
    c->o.seed = seed;
    c->o.log_curve = false;
    return sl_gvs_options_check(&c->o, err);
}

static void gvs_release(void *p)
{
    gvs_shared *s = p;
    if (!s)
        return;
    sl_es_destroy(s->es);
    sl_free(&s->a, s, sizeof *s);
}

static sl_status gvs_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                             uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads; /* serial */
    const gvs_config *c = config;
    *removed = 0;
    if (c->o.origins == SL_GVS_ORIGINS_BOUNDARY) {
        const sl_viewcell *vc = sl_viewcells_data(cells);
        for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
            if (vc[i].shape == SL_CELL_CLUSTER)
                return sl_fail(err, SL_ERROR_UNSUPPORTED,
                               "gvs: origins=boundary needs prism or box cells, but cell %u is BSP cluster %d "
                               "(use origins=volume or auto)",
                               i, (int)vc[i].cluster);
    }
    gvs_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->o = c->o;
    sl_status st = sl_es_create(scene, NULL, alloc, &s->es, err);
    if (st != SL_OK) {
        gvs_release(s);
        return st;
    }
    *shared = s;
    return SL_OK;
}

typedef struct gvs_worker {
    gvs_shared *sh;
    sl_gvs g;
} gvs_worker;

static void gvs_worker_destroy(void *p)
{
    gvs_worker *w = p;
    if (!w)
        return;
    sl_gvs_destroy(w->g);
    sl_free(&w->sh->a, w, sizeof *w);
}

static sl_status gvs_worker_create(void *shared, void **worker, sl_error *err)
{
    gvs_shared *s = shared;
    gvs_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "gvs: out of memory");
    w->sh = s;
    sl_status st = sl_gvs_create(s->es, s->scene, &s->o, &s->a, &w->g, err);
    if (st != SL_OK) {
        gvs_worker_destroy(w);
        return st;
    }
    *worker = w;
    return SL_OK;
}

static sl_status gvs_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    gvs_worker *w = worker;
    sl_gvs_result r;
    sl_status st = sl_gvs_cell(w->g, w->sh->cells, cell, &r, err);
    if (st != SL_OK)
        return st;
    if (r.object_count)
        memcpy(out->ids, r.objects, (size_t)r.object_count * sizeof(uint32_t));
    out->count = r.object_count;
    out->work = r.stats.rays;
    return SL_OK;
}

static void gvs_notice(const void *config, char *buf, size_t size)
{
    const gvs_config *c = config;
    buf[0] = 0;
    if (c->o.sampler == SL_GVS_RANDOM)
        snprintf(buf, size, "sampler=random is the plain random-sampling baseline: it misses far more than gvs at "
                            "the same ray budget");
    else if (c->o.max_rays < c->o.window)
        snprintf(buf, size, "max_rays (%llu) is below window (%llu): the adaptive termination rule never fires",
                 (unsigned long long)c->o.max_rays, (unsigned long long)c->o.window);
}

const sl_pvs_method sl_pvs_method_gvs = {
    .name = "gvs",
    .summary = "guided visibility sampling: Halton rays + adaptive border sampling + reverse sampling with Embree "
               "(Wonka, Wimmer et al. 2006); aggressive, any triangle scene",
    .options_help = g_gvs_help,
    .guarantee = SL_AGGRESSIVE,
    .config_size = sizeof(gvs_config),
    .configure = gvs_configure,
    .prepare = gvs_prepare,
    .worker_create = gvs_worker_create,
    .cell = gvs_cell,
    .worker_destroy = gvs_worker_destroy,
    .release = gvs_release,
    .notice = gvs_notice,
};

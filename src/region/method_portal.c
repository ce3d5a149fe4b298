/* portal: a conservative from-region PVS for Quake III maps, computed from the map's BSP tree by
 * portal flow (docs/pvs.md, "portal").
 *
 *  1. Portals: every node's plane, as a polygon larger than the map, is clipped by the half-spaces
 *     of its ancestors, pushed down its front subtree and each front fragment down its back
 *     subtree; a fragment with an open leaf (cluster >= 0) on both sides is a portal between them.
 *     Splits keep a band of width eps on both sides, so a fragment near a plane goes both ways:
 *     the portals cover the true leaf boundaries (plus slivers), never less.
 *  2. Flow: for a cell (a cluster C), every portal leaving a leaf of C for a leaf outside C is a
 *     source; a depth-first walk through the leaf-portal graph follows every chain of portals a
 *     straight line could stab in order. Each further portal is clipped by the half-spaces that
 *     any line through the (clipped) source and the (clipped) pass portal must reach (the planes
 *     of the source and of separating planes between source and pass, Teller & Séquin), and the
 *     source by the reverse; an empty target ends the branch. Every leaf reached is visible.
 *  3. Objects: every triangle is pushed down the tree with the same eps band; an object belongs to
 *     every open leaf one of its triangles reaches. Objects that no leaf of the map lists (brush
 *     models: doors, platforms, which move) or that reach no open leaf are in every set.
 *
 * Conservative with respect to straight sight lines through open leaves (the region oracle's
 * rule and q3map's vis model): a line from a point of C leaves C through one source portal and then
 * crosses a chain of portals in order, each through a point the clipping keeps (every clipping
 * half-space contains all such lines, widened by eps). Detail geometry inside open leaves is
 * ignored, which only adds objects. Lines through exactly a shared edge of two portals of one leaf
 * (zero length inside it) are the one measure-zero case the separating planes do not follow.
 * Walks are per directed portal, computed once in prepare (smallest flood bound first, so that
 * later walks are bounded by finished ones; in parallel by fixed chunks, deterministic whatever
 * the thread count); a cell is the union of the walks of the portals
 * leaving its cluster. A walk that exceeds `budget` thousand steps stops and takes, for every
 * branch still open, the branch's bound (a superset of what it could reach): conservative too,
 * only larger. The steps are reported as the cells' work. */
#include "pvs_internal.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>

#define PORTAL_MAXV 64    /* vertices of a winding during the flow; a clip that would need more is skipped */
#define PORTAL_GEN_MAXV 256 /* the same during portal generation */
#define PORTAL_CHUNK 64   /* walks per parallel chunk (fixed: the rows must not depend on threads) */
#define PORTAL_MAXSEP 64  /* separators kept per frame (more are dropped: fewer clips keep more) */
#define PORTAL_SEP_TOL 1e-7 /* rounding tolerance of a separating plane's separation (metres) */

typedef struct portal_config {
    float eps;       /* band kept on both sides of every plane, metres */
    uint32_t budget; /* walk steps per source portal before the bound fallback (thousands) */
    uint32_t passes; /* walks of every portal; the first ones on smaller budgets tighten the bounds */
} portal_config;

/* A portal as seen from one of its leaves: into `to`, plane oriented towards `to`. */
typedef struct dportal {
    uint32_t from, to;
    uint32_t first, count; /* vertices in the shared vertex array */
    uint32_t rev;          /* the same portal the other way */
    double plane[4];       /* n·x + d, >= 0 on the `to` side */
} dportal;

typedef struct portal_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    portal_config cfg;
    uint32_t nobj, nleaf;
    const sl_bsp_leaf *leaves;
    double (*verts)[3];
    uint32_t nverts;
    dportal *dp;        /* directed portals, grouped by `from` */
    uint32_t ndp;
    uint32_t *leaf_dp;  /* nleaf + 1: directed portals of leaf l are [leaf_dp[l], leaf_dp[l+1]) */
    uint64_t *reach;    /* ndp rows of lwords bits: the leaves a line through the row's portal
                         * may reach (the flood bound, then the walk's result) */
    uint32_t lwords;
    uint64_t *steps;    /* ndp: walk steps per directed portal (reported as work) */
    uint32_t fallbacks; /* walks that ran over budget */
    uint32_t *leaf_obj_first; /* nleaf + 1, into leaf_obj */
    uint32_t *leaf_obj;
    size_t nleaf_obj;
    uint8_t *always;    /* nobj: in every set */
} portal_shared;

typedef struct portal_frame {
    uint32_t leaf, it, end;
    uint32_t ns, np;
    double s[PORTAL_MAXV][3]; /* clipped source */
    double p[PORTAL_MAXV][3]; /* clipped pass portal (the one entering `leaf`; unused at depth 0) */
    uint32_t nsep;
    double sep[PORTAL_MAXSEP][4]; /* separators of s and p, made once for all of leaf's portals */
} portal_frame;

typedef struct portal_worker {
    portal_shared *sh;
    uint64_t *vis;      /* lwords: the cell's visible leaves */
    uint8_t *mark;      /* nobj + 1 */
} portal_worker;

/* ---- windings ---- */

static inline double pl_dist(const double pl[4], const double v[3])
{
    return pl[0] * v[0] + pl[1] * v[1] + pl[2] * v[2] + pl[3];
}

/* Smallest and largest signed distance of w's n vertices to pl. */
static void dist_range(const double pl[4], const double (*w)[3], int n, double *lo, double *hi)
{
    double a = INFINITY, b = -INFINITY;
    for (int i = 0; i < n; i++) {
        double d = pl_dist(pl, w[i]);
        a = d < a ? d : a;
        b = d > b ? d : b;
    }
    *lo = a;
    *hi = b;
}

/* Keep the part of convex polygon in (n vertices) where pl(x) >= -off, into out (cap vertices).
 * Returns the vertex count (< 3: empty), or -1 when out would overflow (the caller keeps in).
 * in and out must not overlap. */
static int clip_keep(const double (*in)[3], int n, const double pl[4], double off, double (*out)[3], int cap)
{
    double d[PORTAL_GEN_MAXV];
    bool any_out = false;
    for (int i = 0; i < n; i++) {
        d[i] = pl_dist(pl, in[i]) + off;
        any_out |= d[i] < 0;
    }
    if (!any_out) {
        if (n > cap)
            return -1;
        memcpy(out, in, (size_t)n * sizeof *out);
        return n;
    }
    int m = 0;
    for (int i = 0; i < n; i++) {
        int j = i + 1 == n ? 0 : i + 1;
        if (d[i] >= 0) {
            if (m >= cap)
                return -1;
            memcpy(out[m++], in[i], sizeof *out);
        }
        if ((d[i] >= 0) != (d[j] >= 0)) {
            if (m >= cap)
                return -1;
            double t = d[i] / (d[i] - d[j]);
            for (int k = 0; k < 3; k++)
                out[m][k] = in[i][k] + t * (in[j][k] - in[i][k]);
            m++;
        }
    }
    return m;
}

/* Clip w (n vertices, capacity cap) in place through scratch tmp; an overflow keeps w unchanged. */
static int clip_inplace(double (*w)[3], int n, const double pl[4], double off, double (*tmp)[3], int cap)
{
    int m = clip_keep((const double(*)[3])w, n, pl, off, tmp, cap);
    if (m < 0)
        return n;
    memcpy(w, tmp, (size_t)(m > 0 ? m : 0) * sizeof *w);
    return m;
}

static void plane_flip(const double in[4], double out[4])
{
    for (int k = 0; k < 4; k++)
        out[k] = -in[k];
}

/* The separating planes of src (ns vertices) and pass (np): planes through an edge of one and a
 * vertex of the other with src entirely on one side and pass on the other. A line crossing src
 * and then pass gets ever farther along such a plane's normal (oriented from src to pass), so
 * every point beyond pass lies at least as far as pass's nearest vertex: out[k] is oriented and
 * shifted so that those points have out[k](x) >= 0. At most cap planes (fewer clips only keep
 * more); returns the count. */
static int make_separators(const double (*src)[3], int ns, const double (*pass)[3], int np, double (*out)[4], int cap)
{
    int n = 0;
    for (int fam = 0; fam < 2; fam++) {
        const double(*ea)[3] = fam == 0 ? src : pass; /* edges from */
        const double(*vb)[3] = fam == 0 ? pass : src; /* vertices from */
        int na = fam == 0 ? ns : np, nb = fam == 0 ? np : ns;
        for (int i = 0; i < na; i++) {
            const double *e0 = ea[i], *e1 = ea[i + 1 == na ? 0 : i + 1];
            double ed[3] = {e1[0] - e0[0], e1[1] - e0[1], e1[2] - e0[2]};
            for (int j = 0; j < nb; j++) {
                if (n == cap)
                    return n;
                double w[3] = {vb[j][0] - e0[0], vb[j][1] - e0[1], vb[j][2] - e0[2]};
                double pl[4] = {ed[1] * w[2] - ed[2] * w[1], ed[2] * w[0] - ed[0] * w[2], ed[0] * w[1] - ed[1] * w[0], 0};
                double len = sqrt(pl[0] * pl[0] + pl[1] * pl[1] + pl[2] * pl[2]);
                if (!(len > 1e-12))
                    continue;
                for (int k = 0; k < 3; k++)
                    pl[k] /= len;
                pl[3] = -(pl[0] * e0[0] + pl[1] * e0[1] + pl[2] * e0[2]);
                double smin, smax, pmin, pmax;
                dist_range(pl, src, ns, &smin, &smax);
                /* a plane through an edge of one polygon has that polygon on one side; when src
                 * straddles it (the other family) neither orientation can separate */
                if (smin < -PORTAL_SEP_TOL && smax > PORTAL_SEP_TOL)
                    continue;
                dist_range(pl, pass, np, &pmin, &pmax);
                if (smax <= pmin + PORTAL_SEP_TOL) {
                    memcpy(out[n], pl, sizeof pl);
                    out[n++][3] -= pmin;
                } else if (pmax <= smin + PORTAL_SEP_TOL) {
                    plane_flip(pl, out[n]);
                    out[n++][3] += pmax;
                }
            }
        }
    }
    return n;
}

/* Clip t (nt vertices) by the separators seps (each kept where >= -eps); returns the count. */
static int clip_by(const double (*seps)[4], int nsep, double (*t)[3], int nt, double eps, double (*tmp)[3])
{
    for (int k = 0; k < nsep && nt >= 3; k++)
        nt = clip_inplace(t, nt, seps[k], eps, tmp, PORTAL_MAXV);
    return nt;
}

/* ---- portal generation ---- */

typedef struct gen_ctx {
    const sl_allocator *a;
    const sl_bsp_view *bv;
    double eps;
    double (*planes)[4];
    sl_status st;
    /* output: undirected portals (leaf front, leaf back, vertex range) */
    struct { uint32_t front, back, first, count; double plane[4]; } *por;
    size_t npor, cap_por;
    double (*verts)[3];
    size_t nverts, cap_verts;
    /* fragments of the current node's front subtree */
    struct { uint32_t leaf, first, count; } *frag;
    size_t nfrag, cap_frag;
    double (*fv)[3];
    size_t nfv, cap_fv;
    uint32_t cur_node;
} gen_ctx;

static bool grow(const sl_allocator *a, void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return true;
    size_t nc = *cap ? *cap : 64;
    while (nc < need)
        nc *= 2;
    void *q = sl_realloc(a, *p, *cap * elem, nc * elem);
    if (!q)
        return false;
    *p = q;
    *cap = nc;
    return true;
}

static bool leaf_open(const sl_bsp_view *bv, int32_t child)
{
    return bv->leaves[-(child + 1)].cluster >= 0;
}

/* Which child of node m a polygon lying on m's plane belongs to, seen from the side `normal`
 * points to (the subtree's region lies on that side of the polygon). */
static int coplanar_side(const double mpl[4], const double normal[3])
{
    return mpl[0] * normal[0] + mpl[1] * normal[1] + mpl[2] * normal[2] >= 0 ? 0 : 1;
}

/* Push polygon w down from `child`; region_normal is the normal pointing into the subtree's
 * region at w's plane. Calls emit(leaf, w) for every open leaf reached. */
typedef void (*gen_emit)(gen_ctx *g, uint32_t leaf, const double (*w)[3], int n, void *user);

static void gen_push(gen_ctx *g, int32_t child, const double (*w)[3], int n, const double region_normal[3],
                     gen_emit emit, void *user)
{
    if (g->st != SL_OK || n < 3)
        return;
    if (child < 0) {
        if (leaf_open(g->bv, child))
            emit(g, (uint32_t)(-(child + 1)), w, n, user);
        return;
    }
    const sl_bsp_node *nd = &g->bv->nodes[child];
    const double *pl = g->planes[nd->plane];
    double dmin, dmax;
    dist_range(pl, w, n, &dmin, &dmax);
    bool front = dmax > g->eps, back = dmin < -g->eps;
    if (!front && !back) { /* on the plane */
        gen_push(g, nd->children[coplanar_side(pl, region_normal)], w, n, region_normal, emit, user);
        return;
    }
    if (front && !back) {
        gen_push(g, nd->children[0], w, n, region_normal, emit, user);
        return;
    }
    if (back && !front) {
        gen_push(g, nd->children[1], w, n, region_normal, emit, user);
        return;
    }
    double(*buf)[3] = sl_alloc(g->a, PORTAL_GEN_MAXV * sizeof *buf);
    if (!buf) {
        g->st = SL_ERROR_OUT_OF_MEMORY;
        return;
    }
    double fl[4];
    int m = clip_keep(w, n, pl, g->eps, buf, PORTAL_GEN_MAXV);
    gen_push(g, nd->children[0], m < 0 ? w : (const double(*)[3])buf, m < 0 ? n : m, region_normal, emit, user);
    plane_flip(pl, fl);
    m = clip_keep(w, n, fl, g->eps, buf, PORTAL_GEN_MAXV);
    gen_push(g, nd->children[1], m < 0 ? w : (const double(*)[3])buf, m < 0 ? n : m, region_normal, emit, user);
    sl_free(g->a, buf, PORTAL_GEN_MAXV * sizeof *buf);
}

static void emit_front(gen_ctx *g, uint32_t leaf, const double (*w)[3], int n, void *user)
{
    (void)user;
    if (!grow(g->a, (void **)&g->frag, &g->cap_frag, g->nfrag + 1, sizeof *g->frag) ||
        !grow(g->a, (void **)&g->fv, &g->cap_fv, g->nfv + (size_t)n, sizeof *g->fv)) {
        g->st = SL_ERROR_OUT_OF_MEMORY;
        return;
    }
    g->frag[g->nfrag].leaf = leaf;
    g->frag[g->nfrag].first = (uint32_t)g->nfv;
    g->frag[g->nfrag].count = (uint32_t)n;
    g->nfrag++;
    memcpy(g->fv + g->nfv, w, (size_t)n * sizeof *w);
    g->nfv += (size_t)n;
}

static void emit_back(gen_ctx *g, uint32_t leaf, const double (*w)[3], int n, void *user)
{
    uint32_t front = *(const uint32_t *)user;
    if (front == leaf)
        return;
    if (!grow(g->a, (void **)&g->por, &g->cap_por, g->npor + 1, sizeof *g->por) ||
        !grow(g->a, (void **)&g->verts, &g->cap_verts, g->nverts + (size_t)n, sizeof *g->verts)) {
        g->st = SL_ERROR_OUT_OF_MEMORY;
        return;
    }
    g->por[g->npor].front = front;
    g->por[g->npor].back = leaf;
    g->por[g->npor].first = (uint32_t)g->nverts;
    g->por[g->npor].count = (uint32_t)n;
    memcpy(g->por[g->npor].plane, g->planes[g->bv->nodes[g->cur_node].plane], sizeof g->por[g->npor].plane);
    g->npor++;
    memcpy(g->verts + g->nverts, w, (size_t)n * sizeof *w);
    g->nverts += (size_t)n;
}

/* The portals of node `node`, whose ancestors' kept half-spaces are anc[0..depth). */
static void gen_node(gen_ctx *g, uint32_t node, const double (*anc)[4], uint32_t depth, double half)
{
    const double *pl = g->planes[g->bv->nodes[node].plane];
    /* a square of side 2*half on the plane, centred on the plane's point closest to the origin */
    double u[3], v[3], c[3] = {-pl[3] * pl[0], -pl[3] * pl[1], -pl[3] * pl[2]};
    int ax = fabs(pl[0]) < fabs(pl[1]) ? (fabs(pl[0]) < fabs(pl[2]) ? 0 : 2) : (fabs(pl[1]) < fabs(pl[2]) ? 1 : 2);
    double e[3] = {0, 0, 0};
    e[ax] = 1;
    u[0] = pl[1] * e[2] - pl[2] * e[1];
    u[1] = pl[2] * e[0] - pl[0] * e[2];
    u[2] = pl[0] * e[1] - pl[1] * e[0];
    double ul = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int k = 0; k < 3; k++)
        u[k] /= ul;
    v[0] = pl[1] * u[2] - pl[2] * u[1];
    v[1] = pl[2] * u[0] - pl[0] * u[2];
    v[2] = pl[0] * u[1] - pl[1] * u[0];
    double(*w)[3] = sl_alloc(g->a, 2 * PORTAL_GEN_MAXV * sizeof *w);
    if (!w) {
        g->st = SL_ERROR_OUT_OF_MEMORY;
        return;
    }
    double(*tmp)[3] = w + PORTAL_GEN_MAXV;
    static const double sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1};
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++)
            w[i][k] = c[k] + half * (sx[i] * u[k] + sy[i] * v[k]);
    int n = 4;
    for (uint32_t i = 0; i < depth && n >= 3; i++)
        n = clip_inplace(w, n, anc[i], g->eps, tmp, PORTAL_GEN_MAXV);
    if (n >= 3) {
        g->nfrag = 0;
        g->nfv = 0;
        g->cur_node = node;
        double up[3] = {pl[0], pl[1], pl[2]}, down[3] = {-pl[0], -pl[1], -pl[2]};
        gen_push(g, g->bv->nodes[node].children[0], (const double(*)[3])w, n, up, emit_front, NULL);
        for (size_t f = 0; f < g->nfrag && g->st == SL_OK; f++) {
            uint32_t leaf = g->frag[f].leaf;
            /* emit_back appends to the portals only: fv stays put while it is read */
            gen_push(g, g->bv->nodes[node].children[1], (const double(*)[3])(g->fv + g->frag[f].first),
                     (int)g->frag[f].count, down, emit_back, &leaf);
        }
    }
    sl_free(g->a, w, 2 * PORTAL_GEN_MAXV * sizeof *w);
}

/* Walk the tree keeping the ancestors' half-spaces on an explicit stack. */
static sl_status gen_portals(gen_ctx *g)
{
    const sl_bsp_view *bv = g->bv;
    if (bv->node_count == 0)
        return SL_OK;
    double lo = INFINITY, hi = -INFINITY;
    for (uint32_t l = 0; l < bv->leaf_count; l++) {
        const sl_aabb *b = &bv->leaves[l].bounds;
        lo = fmin(lo, fmin(b->min.x, fmin(b->min.y, b->min.z)));
        hi = fmax(hi, fmax(b->max.x, fmax(b->max.y, b->max.z)));
    }
    const sl_aabb *rb = &bv->nodes[0].bounds;
    lo = fmin(lo, fmin(rb->min.x, fmin(rb->min.y, rb->min.z)));
    hi = fmax(hi, fmax(rb->max.x, fmax(rb->max.y, rb->max.z)));
    double half = 4.0 * fmax(fabs(lo), fabs(hi)) + 1000.0;
    /* explicit DFS: entries (node, depth); anc[depth-1] is the half-space the node lies in */
    typedef struct { uint32_t node, depth; double hs[4]; } ent;
    size_t cap = 0, top = 0;
    ent *stack = NULL;
    double(*anc)[4] = sl_alloc(g->a, ((size_t)bv->node_count + 1) * sizeof *anc);
    if (!anc || !grow(g->a, (void **)&stack, &cap, 1, sizeof *stack)) {
        sl_free(g->a, anc, ((size_t)bv->node_count + 1) * sizeof *anc);
        sl_free(g->a, stack, cap * sizeof *stack);
        return SL_ERROR_OUT_OF_MEMORY;
    }
    stack[top++] = (ent){0, 0, {0, 0, 0, 0}};
    while (top > 0 && g->st == SL_OK) {
        ent e = stack[--top];
        if (e.depth > 0)
            memcpy(anc[e.depth - 1], e.hs, sizeof e.hs);
        gen_node(g, e.node, (const double(*)[4])anc, e.depth, half);
        const double *pl = g->planes[bv->nodes[e.node].plane];
        for (int side = 1; side >= 0; side--) {
            int32_t ch = bv->nodes[e.node].children[side];
            if (ch < 0)
                continue;
            if (!grow(g->a, (void **)&stack, &cap, top + 1, sizeof *stack)) {
                g->st = SL_ERROR_OUT_OF_MEMORY;
                break;
            }
            ent c = {(uint32_t)ch, e.depth + 1, {pl[0], pl[1], pl[2], pl[3]}};
            if (side == 1)
                plane_flip(pl, c.hs);
            stack[top++] = c;
        }
    }
    sl_free(g->a, anc, ((size_t)bv->node_count + 1) * sizeof *anc);
    sl_free(g->a, stack, cap * sizeof *stack);
    return g->st;
}

/* ---- objects to leaves ---- */

typedef struct obj_ctx {
    const sl_allocator *a;
    const sl_bsp_view *bv;
    double (*planes)[4];
    double eps;
    uint32_t *leaves; /* open leaves reached by the current object (with duplicates) */
    size_t n, cap;
    bool oom;
} obj_ctx;

static void obj_push(obj_ctx *o, int32_t node, const double (*w)[3], int n)
{
    while (!o->oom && n >= 3) {
        if (node < 0) {
            uint32_t leaf = (uint32_t)(-(node + 1));
            if (o->bv->leaves[leaf].cluster < 0)
                return;
            if (!grow(o->a, (void **)&o->leaves, &o->cap, o->n + 1, sizeof *o->leaves)) {
                o->oom = true;
                return;
            }
            o->leaves[o->n++] = leaf;
            return;
        }
        const sl_bsp_node *nd = &o->bv->nodes[node];
        const double *pl = o->planes[nd->plane];
        double dmin, dmax;
        dist_range(pl, w, n, &dmin, &dmax);
        /* a face within eps of a plane goes to both sides, also one that only touches it (a wall
         * ending at a leaf's edge): such a face can be seen from that leaf along grazing lines
         * (oa_bases5 cell 29 sees object 22 so, 1 pixel), and the map's own lists leave it out */
        bool front = dmax >= -o->eps, back = dmin <= o->eps;
        if (front && !back) {
            node = nd->children[0];
            continue;
        }
        if (back && !front) {
            node = nd->children[1];
            continue;
        }
        double buf[PORTAL_MAXV][3], fl[4];
        int m = clip_keep(w, n, pl, o->eps, buf, PORTAL_MAXV);
        obj_push(o, nd->children[0], m < 0 ? w : (const double(*)[3])buf, m < 0 ? n : m);
        plane_flip(pl, fl);
        m = clip_keep(w, n, fl, o->eps, buf, PORTAL_MAXV);
        if (m < 0) {
            node = nd->children[1];
            continue;
        }
        obj_push(o, nd->children[1], (const double(*)[3])buf, m);
        return;
    }
}

static int cmp_u32(const void *x, const void *y)
{
    uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return (a > b) - (a < b);
}

/* Leaf -> object lists (CSR) and the always-visible objects. */
static sl_status assign_objects(portal_shared *s, const sl_bsp_view *bv, double (*planes)[4], sl_error *err)
{
    const sl_allocator *a = &s->a;
    uint32_t nobj = s->nobj, nleaf = s->nleaf;
    obj_ctx o = {a, bv, planes, s->cfg.eps, NULL, 0, 0, false};
    uint32_t *pairs = NULL; /* (leaf, object) */
    size_t npairs = 0, cap_pairs = 0;
    s->always = sl_calloc(a, nobj ? nobj : 1, 1);
    if (!s->always)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    /* objects the map's leaves do not list: brush models and entities (they move) */
    uint8_t *listed = sl_calloc(a, nobj ? nobj : 1, 1);
    if (!listed)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    for (uint32_t k = 0; k < bv->leaf_object_count; k++)
        if (bv->leaf_objects[k] < nobj)
            listed[bv->leaf_objects[k]] = 1;
    sl_status st = SL_OK;
    for (uint32_t id = 0; id < nobj && st == SL_OK; id++) {
        if (!listed[id]) {
            s->always[id] = 1;
            continue;
        }
        sl_object_view ov = sl_scene_object(s->scene, id);
        sl_mesh_view mv = sl_scene_mesh(s->scene, ov.mesh);
        o.n = 0;
        for (uint32_t t = 0; t < mv.triangle_count && !o.oom; t++) {
            double tri[3][3];
            for (int k = 0; k < 3; k++) {
                uint32_t vi = mv.indices[3 * (size_t)t + (size_t)k];
                sl_vec3 p = {mv.positions[3 * (size_t)vi], mv.positions[3 * (size_t)vi + 1], mv.positions[3 * (size_t)vi + 2]};
                if (!ov.identity)
                    p = sl_affine_point(&ov.transform, p);
                tri[k][0] = p.x;
                tri[k][1] = p.y;
                tri[k][2] = p.z;
            }
            if (bv->node_count == 0) {
                if (bv->leaf_count > 0 && bv->leaves[0].cluster >= 0 &&
                    grow(a, (void **)&o.leaves, &o.cap, o.n + 1, sizeof *o.leaves))
                    o.leaves[o.n++] = 0;
                continue;
            }
            /* a degenerate triangle (collapsed patch edge) goes down like any other: clipping
             * keeps its points, so it reaches the leaves it lies in */
            obj_push(&o, 0, (const double(*)[3])tri, 3);
        }
        if (o.oom) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
            break;
        }
        if (o.n == 0) {
            s->always[id] = 1;
            continue;
        }
        qsort(o.leaves, o.n, sizeof *o.leaves, cmp_u32);
        for (size_t k = 0; k < o.n; k++) {
            if (k > 0 && o.leaves[k] == o.leaves[k - 1])
                continue;
            if (!grow(a, (void **)&pairs, &cap_pairs, 2 * (npairs + 1), sizeof *pairs)) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
                break;
            }
            pairs[2 * npairs] = o.leaves[k];
            pairs[2 * npairs + 1] = id;
            npairs++;
        }
    }
    sl_free(a, listed, nobj ? nobj : 1);
    sl_free(a, o.leaves, o.cap * sizeof *o.leaves);
    if (st == SL_OK) {
        s->leaf_obj_first = sl_calloc(a, (size_t)nleaf + 1, sizeof *s->leaf_obj_first);
        s->leaf_obj = sl_alloc(a, (npairs ? npairs : 1) * sizeof *s->leaf_obj);
        s->nleaf_obj = npairs;
        if (!s->leaf_obj_first || !s->leaf_obj)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    }
    if (st == SL_OK) {
        /* counting sort by leaf; objects come in ascending id order within a leaf */
        for (size_t k = 0; k < npairs; k++)
            s->leaf_obj_first[pairs[2 * k] + 1]++;
        for (uint32_t l = 0; l < nleaf; l++)
            s->leaf_obj_first[l + 1] += s->leaf_obj_first[l];
        uint32_t *at = sl_alloc(a, ((size_t)nleaf + 1) * sizeof *at);
        if (!at)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
        else {
            memcpy(at, s->leaf_obj_first, ((size_t)nleaf + 1) * sizeof *at);
            for (size_t k = 0; k < npairs; k++)
                s->leaf_obj[at[pairs[2 * k]]++] = pairs[2 * k + 1];
            sl_free(a, at, ((size_t)nleaf + 1) * sizeof *at);
        }
    }
    sl_free(a, pairs, cap_pairs * sizeof *pairs);
    return st;
}

/* ---- method ---- */

static sl_status portal_configure(sl_opts *o, void *config, sl_error *err)
{
    portal_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "eps", 0.001f, 1e-6f, 0.1f, &c->eps, err)) != SL_OK ||
        (st = sl_opts_u32(o, "budget", 50, 1, 1000000, &c->budget, err)) != SL_OK ||
        (st = sl_opts_u32(o, "passes", 1, 1, 8, &c->passes, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void portal_release(void *p)
{
    portal_shared *s = p;
    if (!s)
        return;
    const sl_allocator *a = &s->a;
    sl_free(a, s->verts, (size_t)(s->nverts ? s->nverts : 1) * sizeof *s->verts);
    sl_free(a, s->dp, (size_t)(s->ndp ? s->ndp : 1) * sizeof *s->dp);
    sl_free(a, s->leaf_dp, ((size_t)s->nleaf + 1) * sizeof *s->leaf_dp);
    sl_free(a, s->reach, (size_t)(s->ndp ? s->ndp : 1) * s->lwords * sizeof *s->reach);
    sl_free(a, s->steps, (size_t)(s->ndp ? s->ndp : 1) * sizeof *s->steps);
    sl_free(a, s->leaf_obj_first, ((size_t)s->nleaf + 1) * sizeof *s->leaf_obj_first);
    sl_free(a, s->leaf_obj, (s->nleaf_obj ? s->nleaf_obj : 1) * sizeof *s->leaf_obj);
    sl_free(a, s->always, s->nobj ? s->nobj : 1);
    sl_allocator copy = *a;
    sl_free(&copy, s, sizeof *s);
}

/* Some vertex of r within eps in front of plane pl. */
static bool any_ahead(const portal_shared *s, const dportal *r, const double pl[4])
{
    for (uint32_t v = 0; v < r->count; v++)
        if (pl_dist(pl, s->verts[r->first + v]) > -(double)s->cfg.eps)
            return true;
    return false;
}

static inline bool bit(const uint64_t *row, uint32_t i) { return (row[i >> 6] >> (i & 63)) & 1; }
static inline void bit_set(uint64_t *row, uint32_t i) { row[i >> 6] |= 1ull << (i & 63); }

/* reach[q] before the walks: every leaf reachable from q's far leaf through portals r that have a
 * point in front of q's plane while q has a point behind r's plane. A line crossing q and then a
 * chain of portals meets both conditions at each of them, so the row bounds what any walk can
 * reach after crossing q. */
static sl_status might_see(portal_shared *s, sl_error *err)
{
    const sl_allocator *a = &s->a;
    s->lwords = (s->nleaf + 63) / 64 ? (s->nleaf + 63) / 64 : 1;
    s->reach = sl_calloc(a, (size_t)(s->ndp ? s->ndp : 1) * s->lwords, sizeof *s->reach);
    uint32_t *queue = sl_alloc(a, ((size_t)s->nleaf + 1) * sizeof *queue);
    uint8_t *seen = sl_calloc(a, (size_t)s->nleaf + 1, 1);
    sl_status st = SL_OK;
    if (!s->reach || !queue || !seen)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory for %u portals' visibility bits", s->ndp);
    for (uint32_t qi = 0; qi < s->ndp && st == SL_OK; qi++) {
        const dportal *q = &s->dp[qi];
        uint64_t *row = s->reach + (size_t)qi * s->lwords;
        double back[4];
        uint32_t head = 0, tail = 0;
        queue[tail++] = q->to;
        seen[q->to] = 1;
        seen[q->from] = 1;
        bit_set(row, q->to);
        while (head < tail) {
            uint32_t l = queue[head++];
            for (uint32_t k = s->leaf_dp[l]; k < s->leaf_dp[l + 1]; k++) {
                const dportal *r = &s->dp[k];
                if (seen[r->to] || !any_ahead(s, r, q->plane))
                    continue;
                plane_flip(r->plane, back);
                if (!any_ahead(s, q, back))
                    continue;
                bit_set(row, r->to);
                seen[r->to] = 1;
                queue[tail++] = r->to;
            }
        }
        for (uint32_t i = 0; i < tail; i++)
            seen[queue[i]] = 0;
        seen[q->from] = 0;
    }
    sl_free(a, queue, ((size_t)s->nleaf + 1) * sizeof *queue);
    sl_free(a, seen, (size_t)s->nleaf + 1);
    return st;
}

/* ---- the walks ---- */

typedef struct walker {
    portal_shared *sh;
    uint8_t *onstack;
    uint32_t *queue;
    uint64_t *vis;      /* lwords: leaves the current source reaches */
    portal_frame *frames;
    uint32_t frame_cap;
    uint64_t *bounds;   /* bound_cap rows of lwords: what each frame's branch might still reach */
    uint32_t bound_cap;
} walker;

static void walker_free(walker *w)
{
    const sl_allocator *a = &w->sh->a;
    sl_free(a, w->onstack, (size_t)w->sh->nleaf + 1);
    sl_free(a, w->queue, ((size_t)w->sh->nleaf + 1) * sizeof *w->queue);
    sl_free(a, w->vis, (size_t)w->sh->lwords * sizeof *w->vis);
    sl_free(a, w->frames, w->frame_cap * sizeof *w->frames);
    sl_free(a, w->bounds, (size_t)w->bound_cap * w->sh->lwords * sizeof *w->bounds);
}

static bool walker_init(walker *w, portal_shared *s)
{
    memset(w, 0, sizeof *w);
    w->sh = s;
    w->onstack = sl_calloc(&s->a, (size_t)s->nleaf + 1, 1);
    w->queue = sl_alloc(&s->a, ((size_t)s->nleaf + 1) * sizeof *w->queue);
    w->vis = sl_alloc(&s->a, (size_t)s->lwords * sizeof *w->vis);
    w->frame_cap = w->bound_cap = 16;
    w->frames = sl_alloc(&s->a, w->frame_cap * sizeof *w->frames);
    w->bounds = sl_alloc(&s->a, (size_t)w->bound_cap * s->lwords * sizeof *w->bounds);
    if (!w->onstack || !w->queue || !w->vis || !w->frames || !w->bounds) {
        walker_free(w);
        return false;
    }
    return true;
}

/* Grow the walk's stacks to hold frame `need`. */
static bool frames_reserve(walker *w, uint32_t need)
{
    portal_shared *s = w->sh;
    if (need >= w->frame_cap) {
        portal_frame *nf = sl_realloc(&s->a, w->frames, w->frame_cap * sizeof *nf, 2 * w->frame_cap * sizeof *nf);
        if (!nf)
            return false;
        w->frames = nf;
        w->frame_cap *= 2;
    }
    if (need >= w->bound_cap) {
        size_t row = (size_t)s->lwords * sizeof *w->bounds;
        uint64_t *nb = sl_realloc(&s->a, w->bounds, w->bound_cap * row, 2 * (size_t)w->bound_cap * row);
        if (!nb)
            return false;
        w->bounds = nb;
        w->bound_cap *= 2;
    }
    return true;
}

/* Connectivity fallback for a source whose walk ran over budget: every leaf reachable from the
 * source's far leaf through portals with a point in front of the source's plane. */
static void flood_from(walker *w, const dportal *src)
{
    portal_shared *s = w->sh;
    uint8_t *seen = w->onstack; /* all clear after an abandoned walk */
    uint32_t head = 0, tail = 0;
    w->queue[tail++] = src->to;
    seen[src->to] = 1;
    seen[src->from] = 1;
    while (head < tail) {
        uint32_t l = w->queue[head++];
        bit_set(w->vis, l);
        for (uint32_t k = s->leaf_dp[l]; k < s->leaf_dp[l + 1]; k++) {
            const dportal *q = &s->dp[k];
            if (seen[q->to] || !any_ahead(s, q, src->plane))
                continue;
            seen[q->to] = 1;
            w->queue[tail++] = q->to;
        }
    }
    for (uint32_t i = 0; i < tail; i++)
        seen[w->queue[i]] = 0;
    seen[src->from] = 0;
}

/* The walk from directed portal si (docs/pvs.md, "portal"): the leaves it reaches replace
 * reach[si]. A branch through portal q is bounded by reach[q] (the flood bound, or the finished
 * walk of q: a line through the branch crosses q, so whatever it sees lies in q's walk) and goes
 * on only while that bound holds a leaf not yet reached. */
static sl_status flow(walker *w, uint32_t si, uint64_t limit, uint64_t *row, bool *over_budget)
{
    portal_shared *s = w->sh;
    const dportal *src = &s->dp[si];
    const double eps = s->cfg.eps;
    const uint32_t words = s->lwords;
    uint64_t steps = 0;
    double tmp[PORTAL_MAXV][3], t[PORTAL_MAXV][3], back[4];
    memset(w->vis, 0, words * sizeof *w->vis);
    bit_set(w->vis, src->to);
    bool over = false;
    sl_status st = SL_OK;
    uint32_t top = 0;
    if (src->count <= PORTAL_MAXV) { /* else too many vertices to follow: connectivity */
        portal_frame *f = &w->frames[0];
        f->leaf = src->to;
        f->it = s->leaf_dp[src->to];
        f->end = s->leaf_dp[src->to + 1];
        f->ns = src->count;
        f->np = 0;
        f->nsep = 0;
        memcpy(f->s, s->verts + src->first, src->count * sizeof *f->s);
        memcpy(w->bounds, s->reach + (size_t)si * words, words * sizeof *w->bounds);
        w->onstack[src->from] = 1;
        w->onstack[src->to] = 1;
    }
    while (src->count <= PORTAL_MAXV) {
        portal_frame *f = &w->frames[top];
        const uint64_t *fb = w->bounds + (size_t)top * words;
        if (f->it == f->end) {
            w->onstack[f->leaf] = 0;
            if (top == 0)
                break;
            top--;
            continue;
        }
        uint32_t qi = f->it++;
        const dportal *q = &s->dp[qi];
        if (!bit(fb, q->to) || w->onstack[q->to] || q->count > PORTAL_MAXV)
            continue;
        if (++steps > limit) {
            /* over budget: every branch still open reaches only leaves within its frame's bound */
            for (uint32_t k = 0; k <= top; k++) {
                const uint64_t *b = w->bounds + (size_t)k * words;
                for (uint32_t j = 0; j < words; j++)
                    w->vis[j] |= b[j];
            }
            over = true;
            break;
        }
        /* target: in front of the source's plane, inside the source-pass anti-penumbra */
        memcpy(t, s->verts + q->first, q->count * sizeof *t);
        int nt = clip_inplace(t, (int)q->count, src->plane, eps, tmp, PORTAL_MAXV);
        if (nt >= 3)
            nt = clip_by((const double(*)[4])f->sep, (int)f->nsep, t, nt, eps, tmp);
        if (nt < 3)
            continue;
        if (!frames_reserve(w, top + 1)) {
            st = SL_ERROR_OUT_OF_MEMORY;
            break;
        }
        f = &w->frames[top];
        fb = w->bounds + (size_t)top * words;
        portal_frame *g = &w->frames[top + 1];
        /* source: behind the target's plane, inside the target-pass anti-penumbra (reversed) */
        memcpy(g->s, f->s, f->ns * sizeof *g->s);
        plane_flip(q->plane, back);
        int ns = clip_inplace(g->s, (int)f->ns, back, eps, tmp, PORTAL_MAXV);
        if (ns >= 3 && f->np > 0) {
            double rsep[PORTAL_MAXSEP][4];
            int nr = make_separators((const double(*)[3])t, nt, (const double(*)[3])f->p, (int)f->np, rsep,
                                     PORTAL_MAXSEP);
            ns = clip_by((const double(*)[4])rsep, nr, g->s, ns, eps, tmp);
        }
        if (ns < 3)
            continue;
        bit_set(w->vis, q->to);
        uint64_t *gb = w->bounds + (size_t)(top + 1) * words, more = 0;
        const uint64_t *qb = s->reach + (size_t)qi * words;
        for (uint32_t k = 0; k < words; k++) {
            gb[k] = fb[k] & qb[k];
            more |= gb[k] & ~w->vis[k];
        }
        if (!more)
            continue;
        g->ns = (uint32_t)ns;
        g->np = (uint32_t)nt;
        memcpy(g->p, t, (size_t)nt * sizeof *g->p);
        g->nsep = (uint32_t)make_separators((const double(*)[3])g->s, ns, (const double(*)[3])g->p, nt, g->sep,
                                            PORTAL_MAXSEP);
        g->leaf = q->to;
        g->it = s->leaf_dp[q->to];
        g->end = s->leaf_dp[q->to + 1];
        w->onstack[q->to] = 1;
        top++;
    }
    if ((over || st != SL_OK) && src->count <= PORTAL_MAXV)
        for (uint32_t k = 0; k <= top; k++)
            w->onstack[w->frames[k].leaf] = 0;
    w->onstack[src->from] = 0;
    if (st != SL_OK)
        return st;
    if (src->count > PORTAL_MAXV)
        flood_from(w, src);
    *over_budget = over;
    s->steps[si] = steps;
    memcpy(row, w->vis, words * sizeof *w->vis);
    return SL_OK;
}

typedef struct order_key { uint32_t count, index; } order_key;

static int cmp_order(const void *x, const void *y)
{
    const order_key *a = x, *b = y;
    if (a->count != b->count)
        return a->count < b->count ? -1 : 1;
    return (a->index > b->index) - (a->index < b->index);
}

/* Walk every directed portal, those with the smallest flood bound first, so that the bigger
 * walks find the finished (tighter) rows of the portals they cross. The order is cut into fixed
 * chunks walked in parallel: a walk reads the rows as they were before its chunk (its chunk's
 * results are committed after it), so the rows do not depend on the thread count. */
static sl_status walk_all(portal_shared *s, uint32_t threads, sl_error *err)
{
    const sl_allocator *a = &s->a;
    const size_t nd = s->ndp ? s->ndp : 1, row = (size_t)s->lwords;
    s->steps = sl_calloc(a, nd, sizeof *s->steps);
    order_key *ord = sl_alloc(a, nd * sizeof *ord);
    uint64_t *buf = sl_alloc(a, PORTAL_CHUNK * row * sizeof *buf);
    if (!s->steps || !ord || !buf) {
        sl_free(a, ord, nd * sizeof *ord);
        sl_free(a, buf, PORTAL_CHUNK * row * sizeof *buf);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory for the portal walks");
    }
    for (uint32_t i = 0; i < s->ndp; i++) {
        const uint64_t *r = s->reach + (size_t)i * row;
        uint32_t c = 0;
        for (uint32_t k = 0; k < s->lwords; k++)
            c += (uint32_t)__builtin_popcountll(r[k]);
        ord[i] = (order_key){c, i};
    }
    qsort(ord, s->ndp, sizeof *ord, cmp_order);
    sl_status st = SL_OK;
    /* every pass but the last runs on a quarter of the next one's budget; the later passes start
     * from the earlier rows, all of them sound bounds */
    for (uint32_t pass = 0; pass < s->cfg.passes && st == SL_OK; pass++) {
        uint64_t limit = (uint64_t)s->cfg.budget * 1000u >> (2 * (s->cfg.passes - 1 - pass));
        limit = limit ? limit : 1;
        for (uint32_t c0 = 0; c0 < s->ndp && st == SL_OK; c0 += PORTAL_CHUNK) {
            int cn = (int)(s->ndp - c0 < PORTAL_CHUNK ? s->ndp - c0 : PORTAL_CHUNK);
            sl_status cst[PORTAL_CHUNK];
            bool over[PORTAL_CHUNK];
            int nt = threads ? (int)threads : omp_get_max_threads();
#pragma omp parallel num_threads(nt)
            {
                walker w;
                bool ok = walker_init(&w, s);
#pragma omp for schedule(dynamic, 1)
                for (int i = 0; i < cn; i++)
                    cst[i] = ok ? flow(&w, ord[c0 + (uint32_t)i].index, limit, buf + (size_t)i * row, &over[i])
                                : SL_ERROR_OUT_OF_MEMORY;
                if (ok)
                    walker_free(&w);
            }
            for (int i = 0; i < cn && st == SL_OK; i++) {
                if (cst[i] != SL_OK) {
                    st = sl_fail(err, cst[i], "portal: out of memory in the walk of portal %u", ord[c0 + (uint32_t)i].index);
                    break;
                }
                memcpy(s->reach + (size_t)ord[c0 + (uint32_t)i].index * row, buf + (size_t)i * row, row * sizeof *buf);
                s->fallbacks += over[i];
            }
        }
    }
    sl_free(a, buf, PORTAL_CHUNK * row * sizeof *buf);
    sl_free(a, ord, nd * sizeof *ord);
    return st;
}

static sl_status portal_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                                uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    *removed = 0;
    sl_bsp_view bv;
    if (!sl_scene_bsp(scene, &bv))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "portal: the scene has no BSP data (not a Quake III map)");
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        if (vc[i].shape != SL_CELL_CLUSTER || (uint32_t)vc[i].cluster >= bv.cluster_count)
            return sl_fail(err, SL_ERROR_UNSUPPORTED, "portal: view cell %u is not a cluster of this map (use --cells bsp)",
                           i);
    portal_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->cfg = *(const portal_config *)config;
    s->nobj = sl_scene_object_count(scene);
    s->nleaf = bv.leaf_count;
    s->leaves = bv.leaves;
    const sl_allocator *a = &s->a;
    sl_status st = SL_OK;
    double(*planes)[4] = sl_alloc(a, (size_t)(bv.plane_count ? bv.plane_count : 1) * sizeof *planes);
    if (!planes) {
        portal_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    }
    for (uint32_t i = 0; i < bv.plane_count; i++) {
        const sl_plane *p = &bv.planes[i];
        double len = sqrt((double)p->a * p->a + (double)p->b * p->b + (double)p->c * p->c);
        if (!(len > 0) || !isfinite(len) || !isfinite(p->d)) {
            sl_free(a, planes, (size_t)(bv.plane_count ? bv.plane_count : 1) * sizeof *planes);
            portal_release(s);
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "portal: BSP plane %u has no valid normal", i);
        }
        planes[i][0] = p->a / len;
        planes[i][1] = p->b / len;
        planes[i][2] = p->c / len;
        planes[i][3] = p->d / len;
    }
    gen_ctx g;
    memset(&g, 0, sizeof g);
    g.a = a;
    g.bv = &bv;
    g.eps = s->cfg.eps;
    g.planes = planes;
    g.st = SL_OK;
    if (gen_portals(&g) != SL_OK)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory while generating portals");
    /* directed portals grouped by the leaf they leave (stable: portal order within a leaf) */
    if (st == SL_OK) {
        s->nverts = (uint32_t)g.nverts;
        s->verts = sl_alloc(a, (g.nverts ? g.nverts : 1) * sizeof *s->verts);
        s->ndp = (uint32_t)(2 * g.npor);
        s->dp = sl_alloc(a, (size_t)(s->ndp ? s->ndp : 1) * sizeof *s->dp);
        s->leaf_dp = sl_calloc(a, (size_t)s->nleaf + 1, sizeof *s->leaf_dp);
        if (!s->verts || !s->dp || !s->leaf_dp || g.npor > UINT32_MAX / 2)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory for %zu portals", g.npor);
    }
    if (st == SL_OK) {
        memcpy(s->verts, g.verts, g.nverts * sizeof *s->verts);
        for (size_t i = 0; i < g.npor; i++) {
            s->leaf_dp[g.por[i].front + 1]++;
            s->leaf_dp[g.por[i].back + 1]++;
        }
        for (uint32_t l = 0; l < s->nleaf; l++)
            s->leaf_dp[l + 1] += s->leaf_dp[l];
        uint32_t *at = sl_alloc(a, ((size_t)s->nleaf + 1) * sizeof *at);
        if (!at)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
        else {
            memcpy(at, s->leaf_dp, ((size_t)s->nleaf + 1) * sizeof *at);
            for (size_t i = 0; i < g.npor; i++) {
                /* the plane's front (>= 0) faces the front leaf: back -> front keeps it */
                dportal bf = {g.por[i].back, g.por[i].front, g.por[i].first, g.por[i].count, 0, {0, 0, 0, 0}};
                memcpy(bf.plane, g.por[i].plane, sizeof bf.plane);
                dportal fb = bf;
                fb.from = g.por[i].front;
                fb.to = g.por[i].back;
                plane_flip(bf.plane, fb.plane);
                uint32_t ib = at[bf.from]++, ifb = at[fb.from]++;
                bf.rev = ifb;
                fb.rev = ib;
                s->dp[ib] = bf;
                s->dp[ifb] = fb;
            }
            sl_free(a, at, ((size_t)s->nleaf + 1) * sizeof *at);
        }
    }
    sl_free(a, g.por, g.cap_por * sizeof *g.por);
    sl_free(a, g.verts, g.cap_verts * sizeof *g.verts);
    sl_free(a, g.frag, g.cap_frag * sizeof *g.frag);
    sl_free(a, g.fv, g.cap_fv * sizeof *g.fv);
    if (st == SL_OK)
        st = might_see(s, err);
    if (st == SL_OK)
        st = walk_all(s, threads, err);
    if (st == SL_OK)
        st = assign_objects(s, &bv, planes, err);
    sl_free(a, planes, (size_t)(bv.plane_count ? bv.plane_count : 1) * sizeof *planes);
    if (st != SL_OK) {
        portal_release(s);
        return st;
    }
    *shared = s;
    return SL_OK;
}

static void portal_worker_destroy(void *p)
{
    portal_worker *w = p;
    if (!w)
        return;
    const sl_allocator *a = &w->sh->a;
    sl_free(a, w->vis, (size_t)w->sh->lwords * sizeof *w->vis);
    sl_free(a, w->mark, (size_t)w->sh->nobj + 1);
    sl_free(a, w, sizeof *w);
}

static sl_status portal_worker_create(void *shared, void **out, sl_error *err)
{
    portal_shared *s = shared;
    portal_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    w->sh = s;
    w->vis = sl_alloc(&s->a, (size_t)s->lwords * sizeof *w->vis);
    w->mark = sl_alloc(&s->a, (size_t)s->nobj + 1);
    if (!w->vis || !w->mark) {
        portal_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "portal: out of memory");
    }
    *out = w;
    return SL_OK;
}

/* A cluster's set: its own leaves, the walks of every portal leaving it, their objects and the
 * objects of every set. */
static sl_status portal_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    (void)err;
    portal_worker *w = worker;
    portal_shared *s = w->sh;
    int32_t c = sl_viewcells_data(s->cells)[cell].cluster;
    memset(w->vis, 0, (size_t)s->lwords * sizeof *w->vis);
    uint64_t work = 0;
    for (uint32_t l = 0; l < s->nleaf; l++) {
        if (s->leaves[l].cluster != c)
            continue;
        bit_set(w->vis, l);
        for (uint32_t k = s->leaf_dp[l]; k < s->leaf_dp[l + 1]; k++)
            if (s->leaves[s->dp[k].to].cluster != c) {
                const uint64_t *row = s->reach + (size_t)k * s->lwords;
                for (uint32_t j = 0; j < s->lwords; j++)
                    w->vis[j] |= row[j];
                work += s->steps[k];
            }
    }
    memcpy(w->mark, s->always, s->nobj);
    for (uint32_t l = 0; l < s->nleaf; l++)
        if (bit(w->vis, l))
            for (uint32_t k = s->leaf_obj_first[l]; k < s->leaf_obj_first[l + 1]; k++)
                w->mark[s->leaf_obj[k]] = 1;
    uint32_t n = 0;
    for (uint32_t id = 0; id < s->nobj; id++)
        if (w->mark[id])
            out->ids[n++] = id;
    out->count = n;
    out->work = work;
    return SL_OK;
}

const sl_pvs_method sl_pvs_method_portal = {
    .name = "portal",
    .summary = "conservative from-region PVS of a Quake III map by portal flow through its BSP leaves; bsp cells",
    .options_help =
        "eps=FLOAT (default 0.001): band in metres kept on both sides of every plane when portals, objects and "
        "anti-penumbrae are clipped (larger keeps more)\n"
        "budget=INT (default 50): thousands of walk steps per portal before the open branches take their bounds "
        "(conservative too, but larger sets)\n"
        "passes=INT (default 1): walks of every portal; with more, the earlier passes (a quarter of the next one's "
        "budget each) give the later ones tighter bounds\n",
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(portal_config),
    .configure = portal_configure,
    .prepare = portal_prepare,
    .worker_create = portal_worker_create,
    .cell = portal_cell,
    .worker_destroy = portal_worker_destroy,
    .release = portal_release,
    .notice = NULL,
};

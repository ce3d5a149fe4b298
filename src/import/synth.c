/* Conservative occluder synthesis (sl_synth_occluders, import.h; docs/occluder-synthesis.md).
 *
 * Per object: weld the world-space triangles within a tolerance, check that the welded mesh is
 * closed and consistently oriented (every undirected edge used by exactly two triangles, once in
 * each direction), voxelise it on a grid of its own, call a voxel solid when it touches no
 * triangle (separating-axis test against the voxel grown by a margin) and its winding number
 * (signed ray crossings along +z through a jittered point of the voxel's column) is not zero,
 * merge solid voxels greedily into boxes, grow each box face towards the surface while the grown
 * slab touches no triangle, and add the boxes as 12-triangle occluder meshes of the object.
 *
 * Why a box is inside: a box is a connected set touching no triangle of the welded mesh (margin
 * included), so the winding number is constant on it, and it contains a solid voxel, where it is
 * not zero. Every segment from a point outside the object's bounds to a point of the box therefore
 * crosses the welded surface, which lies within the weld tolerance of the real one (the margin is
 * larger): what the box hides from an eye outside the object, the object's own surface hides. */
#include "core/sl_core.h"
#include "sightline/import.h"
#include "sightline/scene.h"

#include <math.h>
#include <stdlib.h>
#include <time.h>

#define SYNTH_DEFAULT_PER_OBJECT 16u
#define SYNTH_DEFAULT_PER_SCENE 65536u
#define SYNTH_DEFAULT_MAX_VOXELS (1u << 21)
#define SYNTH_DEFAULT_RES 48.0      /* voxels along an object's longest side */
#define SYNTH_DEFAULT_THIN 6.0      /* at least this many voxels across its shortest side */

sl_synth_options sl_synth_defaults(void)
{
    sl_synth_options o;
    memset(&o, 0, sizeof o);
    return o;
}

static double thread_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

typedef struct dv3 { double x, y, z; } dv3;

/* min and max without libm's NaN rules (every value here is finite): inlined */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }
#define fmin dmin
#define fmax dmax

/* one object's welded mesh in world space */
typedef struct wmesh {
    dv3 *v;          /* welded vertices */
    uint32_t nv;
    uint32_t *t;     /* 3 per triangle, degenerate (repeated index) ones dropped */
    uint32_t nt;
    size_t tcap;     /* triangles w->t has room for */
    dv3 lo, hi;      /* bounds */
} wmesh;

/* a candidate box (world, double) */
typedef struct cbox {
    double lo[3], hi[3];
    double volume;
    uint32_t object;
    uint32_t order;  /* creation order: the deterministic tie-break */
} cbox;

typedef struct ctx {
    const sl_allocator *a;
    sl_synth_options opt;
    double weld, margin;
    bool base;       /* the object being made is closed but for its base (its cap lies in z = lo.z) */
    double base_z;
    sl_array boxes;  /* cbox */
    sl_synth_stats *st;
} ctx;

/* ---- welding ---- */

typedef struct hslot { int64_t k[3]; uint32_t id; } hslot;

static uint64_t key_hash(const int64_t k[3])
{
    uint64_t h = (uint64_t)k[0] * 0x9E3779B97F4A7C15ull ^ (uint64_t)k[1] * 0xC2B2AE3D27D4EB4Full ^
                 (uint64_t)k[2] * 0x165667B19E3779F9ull;
    return h ^ (h >> 29);
}

static sl_status weld_object(ctx *c, sl_scene scene, uint32_t object, wmesh *w, sl_error *err)
{
    memset(w, 0, sizeof *w);
    sl_object_view ov = sl_scene_object(scene, object);
    sl_mesh_view mv = sl_scene_mesh(scene, ov.mesh);
    uint32_t n = mv.vertex_count;
    size_t cap = 16;
    while (cap < 2 * (size_t)n)
        cap *= 2;
    hslot *tab = sl_alloc(c->a, cap * sizeof *tab);
    uint32_t *remap = sl_alloc(c->a, (n ? n : 1) * sizeof *remap);
    w->v = sl_alloc(c->a, (n ? n : 1) * sizeof *w->v);
    w->tcap = mv.triangle_count ? mv.triangle_count : 1;
    w->t = sl_alloc(c->a, 3 * w->tcap * sizeof *w->t);
    if (!tab || !remap || !w->v || !w->t) {
        sl_free(c->a, tab, cap * sizeof *tab);
        sl_free(c->a, remap, (n ? n : 1) * sizeof *remap);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory for welding");
    }
    for (size_t i = 0; i < cap; i++)
        tab[i].id = SL_NONE;
    const float *m = ov.transform.m;
    w->lo = (dv3){INFINITY, INFINITY, INFINITY};
    w->hi = (dv3){-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; i++) {
        const float *p = mv.positions + 3 * (size_t)i;
        dv3 q = {p[0], p[1], p[2]};
        if (!ov.identity)
            q = (dv3){m[0] * q.x + m[1] * q.y + m[2] * q.z + m[3], m[4] * q.x + m[5] * q.y + m[6] * q.z + m[7],
                      m[8] * q.x + m[9] * q.y + m[10] * q.z + m[11]};
        int64_t k[3] = {(int64_t)floor(q.x / c->weld), (int64_t)floor(q.y / c->weld), (int64_t)floor(q.z / c->weld)};
        size_t h = key_hash(k) & (cap - 1);
        while (tab[h].id != SL_NONE && memcmp(tab[h].k, k, sizeof k) != 0)
            h = (h + 1) & (cap - 1);
        if (tab[h].id == SL_NONE) {
            memcpy(tab[h].k, k, sizeof k);
            tab[h].id = w->nv;
            w->v[w->nv++] = q;
            w->lo = (dv3){fmin(w->lo.x, q.x), fmin(w->lo.y, q.y), fmin(w->lo.z, q.z)};
            w->hi = (dv3){fmax(w->hi.x, q.x), fmax(w->hi.y, q.y), fmax(w->hi.z, q.z)};
        }
        remap[i] = tab[h].id;
    }
    for (uint32_t t = 0; t < mv.triangle_count; t++) {
        uint32_t a = remap[mv.indices[3 * t]], b = remap[mv.indices[3 * t + 1]], d = remap[mv.indices[3 * t + 2]];
        if (a == b || b == d || a == d)
            continue; /* collapsed by the weld: no area, no surface */
        w->t[3 * w->nt] = a;
        w->t[3 * w->nt + 1] = b;
        w->t[3 * w->nt + 2] = d;
        w->nt++;
    }
    sl_free(c->a, tab, cap * sizeof *tab);
    sl_free(c->a, remap, (n ? n : 1) * sizeof *remap);
    return SL_OK;
}

static void wmesh_free(ctx *c, sl_scene scene, uint32_t object, wmesh *w)
{
    sl_mesh_view mv = sl_scene_mesh(scene, sl_scene_object(scene, object).mesh);
    sl_free(c->a, w->v, (mv.vertex_count ? mv.vertex_count : 1) * sizeof *w->v);
    sl_free(c->a, w->t, 3 * w->tcap * sizeof *w->t);
}

/* ---- closedness ---- */

typedef struct hedge { uint32_t a, b; } hedge; /* directed a -> b */

static int hedge_cmp(const void *x, const void *y)
{
    const hedge *p = x, *q = y;
    uint32_t pa = SL_MIN(p->a, p->b), pb = SL_MAX(p->a, p->b), qa = SL_MIN(q->a, q->b), qb = SL_MAX(q->a, q->b);
    if (pa != qa)
        return pa < qa ? -1 : 1;
    if (pb != qb)
        return pb < qb ? -1 : 1;
    return (p->a > q->a) - (p->a < q->a);
}

typedef struct hedge_t { uint32_t a, b, t; } hedge_t; /* directed a -> b, of triangle t */

static int hedge_t_cmp(const void *x, const void *y)
{
    const hedge_t *p = x, *q = y;
    hedge h1 = {p->a, p->b}, h2 = {q->a, q->b};
    int r = hedge_cmp(&h1, &h2);
    return r ? r : (p->t > q->t) - (p->t < q->t);
}

static uint32_t uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

/* T-junctions: a vertex of the mesh lying on another triangle's open edge, strictly between its
 * ends (exporters split a façade into bays and floors whose corners meet a side wall's edge that is
 * one segment): that edge is then used once on one side and in pieces on the other, and the
 * surface reads as open. Each such triangle is split at those vertices into a fan (the same
 * surface: every new vertex lies on the old edge within tol), until no edge used once has a vertex
 * on it; the closedness test then sees the shell as it is. *split counts the triangles split.
 * Returns 0, or -1 out of memory. */
static int split_t_junctions(ctx *c, wmesh *w, double tol, uint32_t *split)
{
    *split = 0;
    if (w->nt < 2 || w->nv < 4)
        return 0;
    /* a grid over the object's vertices: cells of about a 24th of its longest side */
    double ext = fmax(w->hi.x - w->lo.x, fmax(w->hi.y - w->lo.y, w->hi.z - w->lo.z));
    double cell = fmax(ext / 24, 8 * tol);
    uint32_t gn[3];
    double go[3] = {w->lo.x - tol, w->lo.y - tol, w->lo.z - tol};
    double gext[3] = {w->hi.x - w->lo.x, w->hi.y - w->lo.y, w->hi.z - w->lo.z};
    for (int k = 0; k < 3; k++)
        gn[k] = (uint32_t)fmin(64, floor((gext[k] + 2 * tol) / cell) + 1);
    size_t ncell = (size_t)gn[0] * gn[1] * gn[2];
    uint32_t *cstart = sl_calloc(c->a, ncell + 1, sizeof *cstart), *cv = sl_alloc(c->a, (size_t)w->nv * sizeof *cv);
    uint32_t *fill = sl_alloc(c->a, ncell * sizeof *fill);
    hedge_t *e = NULL;
    size_t ne_cap = 0, touched_n = 0;
    uint8_t *touched = NULL;
    int ret = -1;
    if (!cstart || !cv || !fill)
        goto done;
#define CELL_OF(x, k) ((uint32_t)fmin(gn[k] - 1, fmax(0, floor(((x) - go[k]) / cell))))
#define CELL_INDEX(p) (((size_t)CELL_OF((p)->z, 2) * gn[1] + CELL_OF((p)->y, 1)) * gn[0] + CELL_OF((p)->x, 0))
    for (uint32_t v = 0; v < w->nv; v++)
        cstart[CELL_INDEX(&w->v[v]) + 1]++;
    for (size_t i = 0; i < ncell; i++)
        cstart[i + 1] += cstart[i];
    memcpy(fill, cstart, ncell * sizeof *fill);
    for (uint32_t v = 0; v < w->nv; v++)
        cv[fill[CELL_INDEX(&w->v[v])]++] = v;
    /* each pass splits a triangle at one of its edges at most (one with T-junctions on two edges is
     * finished in the next pass: the fan keeps its other edges) */
    for (int pass = 0; pass < 8; pass++) {
        size_t ne = 3 * (size_t)w->nt;
        sl_free(c->a, touched, touched_n ? touched_n : 1);
        touched_n = w->nt;
        if (!(touched = sl_calloc(c->a, touched_n ? touched_n : 1, 1)))
            goto done;
        if (ne > ne_cap) {
            sl_free(c->a, e, ne_cap * sizeof *e);
            ne_cap = ne;
            if (!(e = sl_alloc(c->a, ne_cap * sizeof *e)))
                goto done;
        }
        for (uint32_t t = 0; t < w->nt; t++)
            for (int k = 0; k < 3; k++)
                e[3 * t + k] = (hedge_t){w->t[3 * t + k], w->t[3 * t + (k + 1) % 3], 3 * t + (uint32_t)k};
        qsort(e, ne, sizeof *e, hedge_t_cmp);
        uint32_t changed = 0;
        for (size_t i = 0; i < ne;) {
            size_t j = i + 1;
            while (j < ne && SL_MIN(e[j].a, e[j].b) == SL_MIN(e[i].a, e[i].b) &&
                   SL_MAX(e[j].a, e[j].b) == SL_MAX(e[i].a, e[i].b))
                j++;
            /* an edge (of the triangles e[i..j)): the vertices strictly inside it, ordered along it;
             * each of its triangles is split there (an edge used twice may have a third surface's
             * vertices on it: a cornice meeting the roof edge above façade bays) */
            size_t first = i;
            i = j;
            uint32_t a = e[first].a, b = e[first].b;
            dv3 pa = w->v[a], pb = w->v[b];
            dv3 d = {pb.x - pa.x, pb.y - pa.y, pb.z - pa.z};
            double len2 = d.x * d.x + d.y * d.y + d.z * d.z, len = sqrt(len2);
            if (!(len > 4 * tol))
                continue;
            uint32_t lo[3], hi[3];
            double elo[3] = {fmin(pa.x, pb.x), fmin(pa.y, pb.y), fmin(pa.z, pb.z)};
            double ehi[3] = {fmax(pa.x, pb.x), fmax(pa.y, pb.y), fmax(pa.z, pb.z)};
            for (int q = 0; q < 3; q++) {
                lo[q] = CELL_OF(elo[q] - tol, q);
                hi[q] = CELL_OF(ehi[q] + tol, q);
            }
            enum { MAXP = 64 };
            uint32_t pv[MAXP];
            double pt[MAXP];
            uint32_t np = 0;
            for (uint32_t z = lo[2]; z <= hi[2]; z++)
                for (uint32_t y = lo[1]; y <= hi[1]; y++)
                    for (uint32_t x = lo[0]; x <= hi[0]; x++) {
                        size_t ci = ((size_t)z * gn[1] + y) * gn[0] + x;
                        for (uint32_t q = cstart[ci]; q < cstart[ci + 1]; q++) {
                            uint32_t v = cv[q];
                            if (v == a || v == b)
                                continue;
                            dv3 r = {w->v[v].x - pa.x, w->v[v].y - pa.y, w->v[v].z - pa.z};
                            double tt = (r.x * d.x + r.y * d.y + r.z * d.z) / len2;
                            if (tt * len <= 2 * tol || (1 - tt) * len <= 2 * tol)
                                continue;
                            dv3 f = {r.x - tt * d.x, r.y - tt * d.y, r.z - tt * d.z};
                            if (f.x * f.x + f.y * f.y + f.z * f.z > tol * tol || np == MAXP)
                                continue;
                            uint32_t at = np++;
                            while (at && pt[at - 1] > tt) {
                                pt[at] = pt[at - 1];
                                pv[at] = pv[at - 1];
                                at--;
                            }
                            pt[at] = tt;
                            pv[at] = v;
                        }
                    }
            if (!np)
                continue;
            for (size_t g = first; g < j; g++) {
                uint32_t t = e[g].t / 3, k = e[g].t % 3, ga = e[g].a, gb = e[g].b, o = w->t[3 * t + (k + 2) % 3];
                if (touched[t])
                    continue; /* split at another edge in this pass: this one waits for the next */
                bool apex = false; /* the triangle's own third vertex on the edge: degenerate, leave it */
                for (uint32_t q = 0; q < np; q++)
                    apex |= pv[q] == o;
                if (apex)
                    continue;
                /* the fan ga, ..., gb around o in the triangle's own orientation (ga -> gb) */
                if ((size_t)w->nt + np > w->tcap) {
                    size_t cap = SL_MAX(2 * w->tcap, (size_t)w->nt + np);
                    uint32_t *grown = sl_realloc(c->a, w->t, 3 * w->tcap * sizeof *grown, 3 * cap * sizeof *grown);
                    if (!grown)
                        goto done;
                    w->t = grown;
                    w->tcap = cap;
                }
                uint32_t prev = ga;
                for (uint32_t q = 0; q <= np; q++) {
                    uint32_t next = q < np ? pv[ga == a ? q : np - 1 - q] : gb;
                    uint32_t *tri = q ? &w->t[3 * (size_t)w->nt++] : &w->t[3 * (size_t)t];
                    tri[0] = prev, tri[1] = next, tri[2] = o;
                    prev = next;
                }
                touched[t] = 1;
                (*split)++;
                changed++;
            }
        }
        if (!changed)
            break;
    }
#undef CELL_INDEX
#undef CELL_OF
    ret = 0;
done:
    sl_free(c->a, cstart, (ncell + 1) * sizeof *cstart);
    sl_free(c->a, cv, (size_t)w->nv * sizeof *cv);
    sl_free(c->a, fill, ncell * sizeof *fill);
    sl_free(c->a, e, ne_cap * sizeof *e);
    sl_free(c->a, touched, touched_n ? touched_n : 1);
    return ret;
}

/* Peel loose parts off: a triangle with a border edge (used by it alone, not in the base plane)
 * cannot belong to a closed surface; remove it, and again for the triangles that this leaves with
 * a border edge (a ledge or a cornice glued on along a wall's edge comes off face by face; a closed
 * shell has no border edge and keeps every triangle). Compacts w->t to the rest; *peeled counts
 * the triangles removed. Returns 0, or -1 out of memory. */
static int peel(ctx *c, wmesh *w, double tol, uint32_t *peeled)
{
    *peeled = 0;
    size_t ne = 3 * (size_t)w->nt;
    uint32_t nt0 = w->nt;
    if (!ne)
        return 0;
    hedge_t *e = sl_alloc(c->a, ne * sizeof *e);
    uint32_t *grp = sl_alloc(c->a, ne * sizeof *grp);       /* per triangle edge (3t+k): its group */
    uint32_t *gfirst = sl_alloc(c->a, (ne + 1) * sizeof *gfirst); /* group g: e[gfirst[g] .. gfirst[g+1]) */
    uint32_t *alive_n = sl_alloc(c->a, ne * sizeof *alive_n);
    uint8_t *base = sl_alloc(c->a, ne), *dead = sl_calloc(c->a, w->nt, 1);
    uint32_t *stack = sl_alloc(c->a, ne * sizeof *stack);
    int ret = -1;
    if (!e || !grp || !gfirst || !alive_n || !base || !dead || !stack)
        goto done;
    for (uint32_t t = 0; t < w->nt; t++)
        for (int k = 0; k < 3; k++)
            e[3 * t + k] = (hedge_t){w->t[3 * t + k], w->t[3 * t + (k + 1) % 3], 3 * t + (uint32_t)k};
    qsort(e, ne, sizeof *e, hedge_t_cmp);
    uint32_t ng = 0;
    for (size_t i = 0; i < ne;) {
        size_t j = i + 1;
        while (j < ne && SL_MIN(e[j].a, e[j].b) == SL_MIN(e[i].a, e[i].b) && SL_MAX(e[j].a, e[j].b) == SL_MAX(e[i].a, e[i].b))
            j++;
        gfirst[ng] = (uint32_t)i;
        alive_n[ng] = (uint32_t)(j - i);
        base[ng] = fabs(w->v[e[i].a].z - w->lo.z) <= tol && fabs(w->v[e[i].b].z - w->lo.z) <= tol;
        for (size_t q = i; q < j; q++)
            grp[e[q].t] = ng;
        ng++;
        i = j;
    }
    gfirst[ng] = (uint32_t)ne;
    size_t sp = 0;
    for (uint32_t g = 0; g < ng; g++)
        if (alive_n[g] == 1 && !base[g])
            stack[sp++] = e[gfirst[g]].t / 3;
    while (sp) {
        uint32_t t = stack[--sp];
        if (dead[t])
            continue;
        dead[t] = 1;
        (*peeled)++;
        for (int k = 0; k < 3; k++) {
            uint32_t g = grp[3 * t + k];
            if (--alive_n[g] == 1 && !base[g])
                for (uint32_t q = gfirst[g]; q < gfirst[g + 1]; q++)
                    if (!dead[e[q].t / 3])
                        stack[sp++] = e[q].t / 3;
        }
    }
    uint32_t kept = 0;
    for (uint32_t t = 0; t < w->nt; t++)
        if (!dead[t]) {
            memmove(&w->t[3 * kept], &w->t[3 * t], 3 * sizeof(uint32_t));
            kept++;
        }
    w->nt = kept;
    ret = 0;
done:
    sl_free(c->a, e, ne * sizeof *e);
    sl_free(c->a, grp, ne * sizeof *grp);
    sl_free(c->a, gfirst, (ne + 1) * sizeof *gfirst);
    sl_free(c->a, alive_n, ne * sizeof *alive_n);
    sl_free(c->a, base, ne);
    sl_free(c->a, dead, nt0 ? nt0 : 1);
    sl_free(c->a, stack, ne * sizeof *stack);
    return ret;
}

/* Keep the closed parts of the welded mesh: its connected components (triangles joined through
 * shared vertices) that are closed and consistently oriented (every edge used by exactly two of
 * their triangles, once in each direction), or so but for holes in the object's base plane (edges
 * used once with both ends at the object's lowest z, within tol: a building standing on the ground
 * without a floor). The other components' triangles are dropped from w (*dropped counts them):
 * the boxes need only lie inside the kept surface, which is drawn as well.
 * Returns 1 (all kept parts closed), 2 (some open in the base plane), 0 (nothing kept) or -1 (out
 * of memory). */
static int keep_closed_parts(ctx *c, wmesh *w, double tol, uint32_t *dropped)
{
    *dropped = 0;
    uint32_t peeled = 0, split = 0;
    /* a quarter of the weld: with the weld's own move (sqrt(3) weld at most) the split surface stays
     * within the 2 weld of the touched margin */
    if (split_t_junctions(c, w, 0.25 * tol, &split) < 0)
        return -1;
    c->st->t_junctions += split;
    if (peel(c, w, tol, &peeled) < 0)
        return -1;
    if (w->nt < 4) {
        *dropped = w->nt + peeled;
        return 0;
    }
    size_t ne = 3 * (size_t)w->nt;
    hedge_t *e = sl_alloc(c->a, ne * sizeof *e);
    uint32_t *parent = sl_alloc(c->a, (size_t)w->nv * sizeof *parent);
    uint8_t *flag = sl_calloc(c->a, w->nv, 1); /* per component root: 1 bad, 2 base holes */
    int ret = -1;
    if (!e || !parent || !flag)
        goto done;
    for (uint32_t v = 0; v < w->nv; v++)
        parent[v] = v;
    for (uint32_t t = 0; t < w->nt; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = uf_find(parent, w->t[3 * t + k]), b = uf_find(parent, w->t[3 * t + (k + 1) % 3]);
            if (a != b)
                parent[SL_MAX(a, b)] = SL_MIN(a, b);
            e[3 * t + k] = (hedge_t){w->t[3 * t + k], w->t[3 * t + (k + 1) % 3], t};
        }
    qsort(e, ne, sizeof *e, hedge_t_cmp);
    for (size_t i = 0; i < ne;) {
        size_t j = i + 1;
        while (j < ne && SL_MIN(e[j].a, e[j].b) == SL_MIN(e[i].a, e[i].b) && SL_MAX(e[j].a, e[j].b) == SL_MAX(e[i].a, e[i].b))
            j++;
        uint32_t root = uf_find(parent, e[i].a);
        if (j - i == 2 && e[i].a == e[i + 1].b) {
            /* shared by two faces, once in each direction */
        } else if (j - i == 1 && fabs(w->v[e[i].a].z - w->lo.z) <= tol && fabs(w->v[e[i].b].z - w->lo.z) <= tol) {
            flag[root] |= 2;
        } else {
            flag[root] |= 1;
        }
        i = j;
    }
    uint32_t kept = 0;
    bool base = false;
    for (uint32_t t = 0; t < w->nt; t++) {
        uint32_t root = uf_find(parent, w->t[3 * t]);
        if (flag[root] & 1)
            continue;
        base = base || (flag[root] & 2);
        memmove(&w->t[3 * kept], &w->t[3 * t], 3 * sizeof(uint32_t));
        kept++;
    }
    *dropped = w->nt - kept + peeled;
    w->nt = kept;
    ret = kept < 4 ? 0 : base ? 2 : 1;
done:
    sl_free(c->a, e, ne * sizeof *e);
    sl_free(c->a, parent, (size_t)w->nv * sizeof *parent);
    sl_free(c->a, flag, w->nv);
    return ret;
}

static double mesh_volume(const wmesh *w)
{
    /* from a point of the base plane: a cap closing holes there adds nothing */
    dv3 o = {(w->lo.x + w->hi.x) / 2, (w->lo.y + w->hi.y) / 2, w->lo.z};
    double v = 0;
    for (uint32_t t = 0; t < w->nt; t++) {
        dv3 p = w->v[w->t[3 * t]], q = w->v[w->t[3 * t + 1]], r = w->v[w->t[3 * t + 2]];
        double px = p.x - o.x, py = p.y - o.y, pz = p.z - o.z, qx = q.x - o.x, qy = q.y - o.y, qz = q.z - o.z;
        double rx = r.x - o.x, ry = r.y - o.y, rz = r.z - o.z;
        v += px * (qy * rz - qz * ry) - py * (qx * rz - qz * rx) + pz * (qx * ry - qy * rx);
    }
    return fabs(v) / 6.0;
}

/* ---- triangle against box (separating axes), box grown by the margin ---- */

static bool tri_box_overlap(const dv3 *p0, const dv3 *p1, const dv3 *p2, const double lo[3], const double hi[3],
                            double margin)
{
    double c[3], h[3];
    for (int k = 0; k < 3; k++) {
        c[k] = (lo[k] + hi[k]) * 0.5;
        h[k] = (hi[k] - lo[k]) * 0.5 + margin;
    }
    double v[3][3] = {{p0->x - c[0], p0->y - c[1], p0->z - c[2]},
                      {p1->x - c[0], p1->y - c[1], p1->z - c[2]},
                      {p2->x - c[0], p2->y - c[1], p2->z - c[2]}};
    for (int k = 0; k < 3; k++) { /* the box's own axes */
        double mn = fmin(v[0][k], fmin(v[1][k], v[2][k])), mx = fmax(v[0][k], fmax(v[1][k], v[2][k]));
        if (mn > h[k] || mx < -h[k])
            return false;
    }
    double e[3][3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            e[i][k] = v[(i + 1) % 3][k] - v[i][k];
    double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                   e[0][0] * e[1][1] - e[0][1] * e[1][0]};
    double d = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
    if (fabs(d) > h[0] * fabs(n[0]) + h[1] * fabs(n[1]) + h[2] * fabs(n[2]))
        return false; /* the triangle's plane */
    for (int i = 0; i < 3; i++)     /* box axis i cross edge j */
        for (int j = 0; j < 3; j++) {
            double ax[3] = {0, 0, 0};
            int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
            ax[i1] = -e[j][i2];
            ax[i2] = e[j][i1];
            double p[3], r = h[0] * fabs(ax[0]) + h[1] * fabs(ax[1]) + h[2] * fabs(ax[2]);
            for (int k = 0; k < 3; k++)
                p[k] = ax[0] * v[k][0] + ax[1] * v[k][1] + ax[2] * v[k][2];
            if (fmin(p[0], fmin(p[1], p[2])) > r || fmax(p[0], fmax(p[1], p[2])) < -r)
                return false;
        }
    return true;
}

/* The same test for many voxels of one size: the 13 axes and the triangle's projection on each,
 * widened by the projected half-size of the grown voxel, computed once per triangle. */
typedef struct tri_sat { double ax[13][3]; double lo[13], hi[13]; } tri_sat;

static void tri_sat_init(tri_sat *s, const dv3 *p0, const dv3 *p1, const dv3 *p2, double half)
{
    double v[3][3] = {{p0->x, p0->y, p0->z}, {p1->x, p1->y, p1->z}, {p2->x, p2->y, p2->z}};
    double e[3][3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            e[i][k] = v[(i + 1) % 3][k] - v[i][k];
    int n = 0;
    double *a = s->ax[n++];
    a[0] = e[0][1] * e[1][2] - e[0][2] * e[1][1], a[1] = e[0][2] * e[1][0] - e[0][0] * e[1][2],
    a[2] = e[0][0] * e[1][1] - e[0][1] * e[1][0];
    for (int i = 0; i < 3; i++) {
        a = s->ax[n++];
        a[0] = a[1] = a[2] = 0;
        a[i] = 1;
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            a = s->ax[n++];
            int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
            a[i] = 0;
            a[i1] = -e[j][i2];
            a[i2] = e[j][i1];
        }
    for (int q = 0; q < 13; q++) {
        a = s->ax[q];
        double r = half * (fabs(a[0]) + fabs(a[1]) + fabs(a[2]));
        double p[3];
        for (int k = 0; k < 3; k++)
            p[k] = a[0] * v[k][0] + a[1] * v[k][1] + a[2] * v[k][2];
        s->lo[q] = fmin(p[0], fmin(p[1], p[2])) - r;
        s->hi[q] = fmax(p[0], fmax(p[1], p[2])) + r;
    }
}

/* Whether the cube of that half-size centred at c overlaps the triangle (no axis separates). */
static inline bool tri_sat_overlap(const tri_sat *s, const double c[3])
{
    for (int q = 0; q < 13; q++) {
        double d = s->ax[q][0] * c[0] + s->ax[q][1] * c[1] + s->ax[q][2] * c[2];
        if (d < s->lo[q] || d > s->hi[q])
            return false;
    }
    return true;
}

/* ---- the column test: signed crossings of the vertical line through (x, y) ---- */

static double seg_dist2(double px, double py, double ax, double ay, double bx, double by)
{
    double dx = bx - ax, dy = by - ay, l = dx * dx + dy * dy;
    double t = l > 0 ? ((px - ax) * dx + (py - ay) * dy) / l : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double qx = ax + t * dx - px, qy = ay + t * dy - py;
    return qx * qx + qy * qy;
}

/* 0: the line misses the triangle; +1/-1: crosses it (sign of the projected area) at *z;
 * 2: too close to an edge or a vertical triangle to say (try another point) */
static int column_cross(const dv3 *a, const dv3 *b, const dv3 *d, double x, double y, double eps, double *z)
{
    if (x < fmin(a->x, fmin(b->x, d->x)) - eps || x > fmax(a->x, fmax(b->x, d->x)) + eps ||
        y < fmin(a->y, fmin(b->y, d->y)) - eps || y > fmax(a->y, fmax(b->y, d->y)) + eps)
        return 0;
    double e2 = eps * eps;
    if (seg_dist2(x, y, a->x, a->y, b->x, b->y) <= e2 || seg_dist2(x, y, b->x, b->y, d->x, d->y) <= e2 ||
        seg_dist2(x, y, d->x, d->y, a->x, a->y) <= e2)
        return 2;
    double o0 = (b->x - a->x) * (y - a->y) - (b->y - a->y) * (x - a->x); /* (a, b, p) */
    double o1 = (d->x - b->x) * (y - b->y) - (d->y - b->y) * (x - b->x); /* (b, d, p) */
    double o2 = (a->x - d->x) * (y - d->y) - (a->y - d->y) * (x - d->x); /* (d, a, p) */
    bool pos = o0 > 0 && o1 > 0 && o2 > 0, neg = o0 < 0 && o1 < 0 && o2 < 0;
    if (!pos && !neg)
        return 0;
    double A = o0 + o1 + o2;
    if (!(fabs(A) > 0))
        return 2;
    *z = (o1 * a->z + o2 * b->z + o0 * d->z) / A;
    return pos ? 1 : -1;
}

/* ---- one object ---- */

typedef struct grid {
    double o[3], v;
    uint32_t n[3];
    uint8_t *cell; /* bit 0 touched, bit 1 solid, bit 2 used */
    size_t count;
} grid;

#define G_AT(g, i, j, k) ((g)->cell[((size_t)(k) * (g)->n[1] + (j)) * (g)->n[0] + (i)])

typedef struct crossing { double z; int s; } crossing;

static int cmp_crossing(const void *x, const void *y)
{
    const crossing *p = x, *q = y;
    if (p->z != q->z)
        return p->z < q->z ? 1 : -1; /* descending */
    return (p->s > q->s) - (p->s < q->s);
}

/* Mark the solid voxels of column (i, j) (winding number of its voxel centres, touched ones
 * excluded). Tries a few points of the column's square; when every one is too close to an edge,
 * the column stays empty. */
static bool solid_column(ctx *c, const wmesh *w, grid *g, uint32_t i, uint32_t j, const uint32_t *tris, uint32_t nt,
                         sl_array *buf)
{
    static const double jit[4][2] = {{0.5, 0.5}, {0.3711, 0.6180}, {0.7071, 0.2929}, {0.1618, 0.8541}};
    double eps = c->margin;
    for (int attempt = 0; attempt < 4; attempt++) {
        double x = g->o[0] + (i + jit[attempt][0]) * g->v, y = g->o[1] + (j + jit[attempt][1]) * g->v;
        buf->count = 0;
        bool bad = false;
        for (uint32_t q = 0; q < nt && !bad; q++) {
            uint32_t t = tris[q];
            double z;
            int r = column_cross(&w->v[w->t[3 * t]], &w->v[w->t[3 * t + 1]], &w->v[w->t[3 * t + 2]], x, y, eps, &z);
            if (r == 2)
                bad = true;
            else if (r != 0) {
                crossing cr = {z, r};
                if (!sl_array_push(c->a, buf, sizeof cr, &cr, 1))
                    return false;
            }
        }
        if (bad)
            continue;
        crossing *cs = buf->data;
        int total = 0;
        for (size_t q = 0; q < buf->count; q++)
            total += cs[q].s;
        if (total != 0 && !c->base)
            return true; /* not a closed surface along this line: nothing solid here */
        if (buf->count > 1)
            qsort(cs, buf->count, sizeof *cs, cmp_crossing);
        size_t q = 0;
        int wn = 0;
        for (int64_t k = (int64_t)g->n[2] - 1; k >= 0; k--) {
            double cz = g->o[2] + ((double)k + 0.5) * g->v;
            while (q < buf->count && cs[q].z > cz)
                wn += cs[q++].s;
            uint8_t *cell = &G_AT(g, i, j, (uint32_t)k);
            if (wn != 0 && !(*cell & 1))
                *cell |= 2;
        }
        return true;
    }
    return true;
}

/* Whether the slab [lo, hi] touches any of the candidate triangles. */
static bool slab_touches(const ctx *c, const wmesh *w, const uint32_t *cand, size_t nc, const double lo[3],
                         const double hi[3])
{
    for (size_t q = 0; q < nc; q++) {
        const uint32_t *t = &w->t[3 * cand[q]];
        if (tri_box_overlap(&w->v[t[0]], &w->v[t[1]], &w->v[t[2]], lo, hi, c->margin))
            return true;
    }
    return false;
}

static sl_status synth_object(ctx *c, const wmesh *w, uint32_t object, double scene_diag, sl_error *err)
{
    double ext[3] = {w->hi.x - w->lo.x, w->hi.y - w->lo.y, w->hi.z - w->lo.z};
    double longest = fmax(ext[0], fmax(ext[1], ext[2])), shortest = fmin(ext[0], fmin(ext[1], ext[2]));
    if (!(shortest > 0))
        return SL_OK;
    double v = c->opt.voxel > 0 ? c->opt.voxel : fmin(longest / SYNTH_DEFAULT_RES, shortest / SYNTH_DEFAULT_THIN);
    v = fmax(v, scene_diag * 1e-5);
    double maxv = c->opt.max_voxels ? c->opt.max_voxels : SYNTH_DEFAULT_MAX_VOXELS;
    for (;;) {
        double cnt = ceil(ext[0] / v) * ceil(ext[1] / v) * ceil(ext[2] / v);
        if (cnt <= maxv)
            break;
        v *= fmax(1.01, cbrt(cnt / maxv));
    }
    grid g;
    g.v = v;
    for (int k = 0; k < 3; k++) {
        g.n[k] = (uint32_t)ceil(ext[k] / v);
        if (g.n[k] < 1)
            g.n[k] = 1;
    }
    g.o[0] = w->lo.x - (g.n[0] * v - ext[0]) / 2;
    g.o[1] = w->lo.y - (g.n[1] * v - ext[1]) / 2;
    g.o[2] = w->lo.z - (g.n[2] * v - ext[2]) / 2;
    g.count = (size_t)g.n[0] * g.n[1] * g.n[2];
    if (g.n[0] < 3 || g.n[1] < 3 || g.n[2] < 3)
        return SL_OK; /* no voxel can be inside */
    g.cell = sl_calloc(c->a, g.count, 1);
    uint32_t *cand = sl_alloc(c->a, (size_t)w->nt * sizeof *cand);
    sl_array buf = {0};
    size_t *col_start = NULL, *col_fill = NULL, col_tris_n = 0;
    uint32_t *col_tris = NULL;
    sl_status st = SL_OK;
    if (!g.cell || !cand) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory for %u voxels", (unsigned)g.count);
        goto done;
    }
    /* 1. voxels the surface touches */
    for (uint32_t t = 0; t < w->nt; t++) {
        const dv3 *p[3] = {&w->v[w->t[3 * t]], &w->v[w->t[3 * t + 1]], &w->v[w->t[3 * t + 2]]};
        int64_t r0[3], r1[3];
        double pl[3] = {fmin(p[0]->x, fmin(p[1]->x, p[2]->x)), fmin(p[0]->y, fmin(p[1]->y, p[2]->y)),
                        fmin(p[0]->z, fmin(p[1]->z, p[2]->z))};
        double ph[3] = {fmax(p[0]->x, fmax(p[1]->x, p[2]->x)), fmax(p[0]->y, fmax(p[1]->y, p[2]->y)),
                        fmax(p[0]->z, fmax(p[1]->z, p[2]->z))};
        for (int k = 0; k < 3; k++) {
            r0[k] = (int64_t)floor((pl[k] - c->margin - g.o[k]) / v) - 1;
            r1[k] = (int64_t)floor((ph[k] + c->margin - g.o[k]) / v) + 1;
            r0[k] = r0[k] < 0 ? 0 : r0[k];
            r1[k] = r1[k] >= (int64_t)g.n[k] ? (int64_t)g.n[k] - 1 : r1[k];
        }
        tri_sat sat;
        tri_sat_init(&sat, p[0], p[1], p[2], 0.5 * v + c->margin);
        for (int64_t k = r0[2]; k <= r1[2]; k++)
            for (int64_t j = r0[1]; j <= r1[1]; j++)
                for (int64_t i = r0[0]; i <= r1[0]; i++) {
                    uint8_t *cell = &G_AT(&g, i, j, k);
                    if (*cell & 1)
                        continue;
                    double cc[3] = {g.o[0] + ((double)i + 0.5) * v, g.o[1] + ((double)j + 0.5) * v,
                                    g.o[2] + ((double)k + 0.5) * v};
                    if (tri_sat_overlap(&sat, cc))
                        *cell |= 1;
                }
    }
    /* the outer layer is never solid (the grid's border touches the bounds) */
    for (uint32_t k = 0; k < g.n[2]; k++)
        for (uint32_t j = 0; j < g.n[1]; j++)
            for (uint32_t i = 0; i < g.n[0]; i++)
                if (i == 0 || j == 0 || k == 0 || i == g.n[0] - 1 || j == g.n[1] - 1 || k == g.n[2] - 1)
                    G_AT(&g, i, j, k) |= 1;
    /* 2. winding number per column, over the triangles binned by the columns their xy box meets */
    size_t ncol = (size_t)g.n[0] * g.n[1];
    col_start = sl_calloc(c->a, ncol + 1, sizeof *col_start);
    if (!col_start) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory");
        goto done;
    }
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            for (size_t q = 0; q < ncol; q++)
                col_start[q + 1] += col_start[q];
            col_tris_n = col_start[ncol];
            col_tris = sl_alloc(c->a, (col_tris_n ? col_tris_n : 1) * sizeof *col_tris);
            col_fill = sl_alloc(c->a, ncol * sizeof *col_fill);
            if (!col_tris || !col_fill) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory for %zu column entries",
                             col_tris_n);
                goto done;
            }
            memcpy(col_fill, col_start, ncol * sizeof *col_fill);
        }
        for (uint32_t t = 0; t < w->nt; t++) {
            const dv3 *p[3] = {&w->v[w->t[3 * t]], &w->v[w->t[3 * t + 1]], &w->v[w->t[3 * t + 2]]};
            double xl = fmin(p[0]->x, fmin(p[1]->x, p[2]->x)) - 2 * c->margin, xh = fmax(p[0]->x, fmax(p[1]->x, p[2]->x)) + 2 * c->margin;
            double yl = fmin(p[0]->y, fmin(p[1]->y, p[2]->y)) - 2 * c->margin, yh = fmax(p[0]->y, fmax(p[1]->y, p[2]->y)) + 2 * c->margin;
            int64_t i0 = (int64_t)floor((xl - g.o[0]) / v), i1 = (int64_t)floor((xh - g.o[0]) / v);
            int64_t j0 = (int64_t)floor((yl - g.o[1]) / v), j1 = (int64_t)floor((yh - g.o[1]) / v);
            i0 = i0 < 0 ? 0 : i0, j0 = j0 < 0 ? 0 : j0;
            i1 = i1 >= (int64_t)g.n[0] ? (int64_t)g.n[0] - 1 : i1, j1 = j1 >= (int64_t)g.n[1] ? (int64_t)g.n[1] - 1 : j1;
            for (int64_t j = j0; j <= j1; j++)
                for (int64_t i = i0; i <= i1; i++) {
                    size_t col = (size_t)j * g.n[0] + (size_t)i;
                    if (pass == 0)
                        col_start[col + 1]++;
                    else
                        col_tris[col_fill[col]++] = t;
                }
        }
    }
    for (uint32_t j = 1; j + 1 < g.n[1]; j++)
        for (uint32_t i = 1; i + 1 < g.n[0]; i++) {
            bool any = false;
            for (uint32_t k = 1; k + 1 < g.n[2] && !any; k++)
                any = !(G_AT(&g, i, j, k) & 1);
            size_t col = (size_t)j * g.n[0] + i;
            if (any && !solid_column(c, w, &g, i, j, col_tris + col_start[col],
                                     (uint32_t)(col_start[col + 1] - col_start[col]), &buf)) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory");
                goto done;
            }
        }
    uint64_t solid = 0;
    for (size_t q = 0; q < g.count; q++)
        solid += (g.cell[q] & 2) != 0;
    c->st->solid_voxels += solid;
    c->st->voxels += g.count;
    /* 3. greedy boxes: grow along x, then y, then z over solid voxels not yet in a box */
#define FREE(i, j, k) ((G_AT(&g, i, j, k) & 6) == 2)
    size_t first_box = c->boxes.count;
    for (uint32_t k = 0; k < g.n[2]; k++)
        for (uint32_t j = 0; j < g.n[1]; j++)
            for (uint32_t i = 0; i < g.n[0]; i++) {
                if (!FREE(i, j, k))
                    continue;
                uint32_t i1 = i, j1 = j, k1 = k;
                while (i1 + 1 < g.n[0] && FREE(i1 + 1, j, k))
                    i1++;
                for (bool ok = true; ok && j1 + 1 < g.n[1];) {
                    for (uint32_t x = i; x <= i1 && ok; x++)
                        ok = FREE(x, j1 + 1, k);
                    if (ok)
                        j1++;
                }
                for (bool ok = true; ok && k1 + 1 < g.n[2];) {
                    for (uint32_t y = j; y <= j1 && ok; y++)
                        for (uint32_t x = i; x <= i1 && ok; x++)
                            ok = FREE(x, y, k1 + 1);
                    if (ok)
                        k1++;
                }
                for (uint32_t z = k; z <= k1; z++)
                    for (uint32_t y = j; y <= j1; y++)
                        for (uint32_t x = i; x <= i1; x++)
                            G_AT(&g, x, y, z) |= 4;
                cbox b;
                b.lo[0] = g.o[0] + i * v, b.lo[1] = g.o[1] + j * v, b.lo[2] = g.o[2] + k * v;
                b.hi[0] = g.o[0] + (i1 + 1) * v, b.hi[1] = g.o[1] + (j1 + 1) * v, b.hi[2] = g.o[2] + (k1 + 1) * v;
                b.volume = (b.hi[0] - b.lo[0]) * (b.hi[1] - b.lo[1]) * (b.hi[2] - b.lo[2]);
                b.object = object;
                b.order = (uint32_t)(c->boxes.count - first_box);
                double edge = fmin(b.hi[0] - b.lo[0], fmin(b.hi[1] - b.lo[1], b.hi[2] - b.lo[2]));
                double min_box = c->opt.min_box > 0 ? c->opt.min_box : 2 * v;
                if (edge + 1e-9 * v < min_box)
                    continue;
                if (!sl_array_push(c->a, &c->boxes, sizeof b, &b, 1)) {
                    st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory for boxes");
                    goto done;
                }
            }
#undef FREE
    /* 4. keep the largest boxes of the object (the budget per object) */
    cbox *B = (cbox *)c->boxes.data + first_box;
    size_t nb = c->boxes.count - first_box;
    uint32_t per = c->opt.max_boxes_per_object ? c->opt.max_boxes_per_object : SYNTH_DEFAULT_PER_OBJECT;
    for (size_t x = 1; x < nb; x++) { /* insertion sort, volume descending, creation order */
        cbox key = B[x];
        size_t y = x;
        while (y > 0 && (B[y - 1].volume < key.volume || (B[y - 1].volume == key.volume && B[y - 1].order > key.order))) {
            B[y] = B[y - 1];
            y--;
        }
        B[y] = key;
    }
    if (nb > per)
        c->boxes.count = first_box + per, nb = per;
    /* 5. grow each face towards the surface while the added slab touches nothing (at most a voxel) */
    if (!c->opt.no_expand) {
        for (size_t x = 0; x < nb; x++) {
            cbox *b = &B[x];
            size_t nc = 0;
            for (uint32_t t = 0; t < w->nt; t++) {
                const dv3 *p[3] = {&w->v[w->t[3 * t]], &w->v[w->t[3 * t + 1]], &w->v[w->t[3 * t + 2]]};
                double q[3][3] = {{p[0]->x, p[1]->x, p[2]->x}, {p[0]->y, p[1]->y, p[2]->y}, {p[0]->z, p[1]->z, p[2]->z}};
                bool near = true;
                for (int k = 0; k < 3 && near; k++)
                    near = fmin(q[k][0], fmin(q[k][1], q[k][2])) <= b->hi[k] + v + c->margin &&
                           fmax(q[k][0], fmax(q[k][1], q[k][2])) >= b->lo[k] - v - c->margin;
                if (near)
                    cand[nc++] = t;
            }
            for (int f = 0; f < 6; f++) {
                int k = f / 2;
                double lo = 0, hi = v;
                for (int it = 0; it < 12; it++) {
                    double mid = (lo + hi) / 2, sl[3], sh[3];
                    memcpy(sl, b->lo, sizeof sl);
                    memcpy(sh, b->hi, sizeof sh);
                    if (f & 1)
                        sl[k] = b->hi[k], sh[k] = b->hi[k] + mid;
                    else
                        sh[k] = b->lo[k], sl[k] = b->lo[k] - mid;
                    if ((c->base && sl[2] < c->base_z + 2 * c->margin) || slab_touches(c, w, cand, nc, sl, sh))
                        hi = mid;
                    else
                        lo = mid;
                }
                if (f & 1)
                    b->hi[k] += lo;
                else
                    b->lo[k] -= lo;
            }
        }
    }
done:
    if (col_start) {
        sl_free(c->a, col_fill, (size_t)g.n[0] * g.n[1] * sizeof *col_fill);
        sl_free(c->a, col_tris, (col_tris_n ? col_tris_n : 1) * sizeof *col_tris);
        sl_free(c->a, col_start, ((size_t)g.n[0] * g.n[1] + 1) * sizeof *col_start);
    }
    sl_array_free(c->a, &buf, sizeof(crossing));
    sl_free(c->a, cand, (size_t)w->nt * sizeof *cand);
    sl_free(c->a, g.cell, g.count);
    return st;
}

static int cbox_cmp_scene(const void *x, const void *y)
{
    const cbox *p = x, *q = y;
    if (p->volume != q->volume)
        return p->volume < q->volume ? 1 : -1;
    if (p->object != q->object)
        return p->object < q->object ? -1 : 1;
    return (p->order > q->order) - (p->order < q->order);
}

static int cbox_cmp_object(const void *x, const void *y)
{
    const cbox *p = x, *q = y;
    if (p->object != q->object)
        return p->object < q->object ? -1 : 1;
    return (p->order > q->order) - (p->order < q->order);
}

/* float bound rounded towards the inside of [lo, hi] */
static float inward(double x, bool up)
{
    float f = (float)x;
    if (up && (double)f < x)
        f = nextafterf(f, INFINITY);
    if (!up && (double)f > x)
        f = nextafterf(f, -INFINITY);
    return f;
}

/* Add boxes B[0..n) (one object's) as one occluder mesh of that object: n closed boxes, 12
 * triangles each, wound outward. *added counts the boxes that went in. */
static sl_status add_boxes(ctx *c, sl_scene scene, const cbox *B, size_t n, uint32_t *added, sl_error *err)
{
    /* outward, counter-clockwise seen from outside; corner i is (i&1 ? hi.x : lo.x, i&2 ..., i&4 ...) */
    static const uint32_t idx[36] = {0, 2, 3, 0, 3, 1, /* -z */ 4, 5, 7, 4, 7, 6, /* +z */
                                     0, 1, 5, 0, 5, 4, /* -y */ 2, 6, 7, 2, 7, 3, /* +y */
                                     0, 4, 6, 0, 6, 2, /* -x */ 1, 3, 7, 1, 7, 5 /* +x */};
    *added = 0;
    float *pos = sl_alloc(c->a, n * 24 * sizeof(float));
    uint32_t *tri = sl_alloc(c->a, n * 36 * sizeof(uint32_t));
    sl_status st = SL_OK;
    if (!pos || !tri) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory for box meshes");
        goto done;
    }
    uint32_t k = 0;
    for (size_t b = 0; b < n; b++) {
        float lo[3], hi[3];
        bool ok = true;
        for (int a = 0; a < 3; a++) {
            lo[a] = inward(B[b].lo[a], true);
            hi[a] = inward(B[b].hi[a], false);
            ok = ok && lo[a] < hi[a];
        }
        if (!ok)
            continue;
        c->st->covered_volume += B[b].volume; /* the voxel box (they are disjoint): a lower bound */
        for (int i = 0; i < 8; i++) {
            pos[24 * k + 3 * i] = (i & 1) ? hi[0] : lo[0];
            pos[24 * k + 3 * i + 1] = (i & 2) ? hi[1] : lo[1];
            pos[24 * k + 3 * i + 2] = (i & 4) ? hi[2] : lo[2];
        }
        for (int i = 0; i < 36; i++)
            tri[36 * k + i] = 8 * k + idx[i];
        k++;
    }
    if (k) {
        sl_mesh_desc md = {pos, NULL, 8 * k, tri, 12 * k, NULL};
        uint32_t mesh;
        st = sl_scene_add_mesh(scene, &md, &mesh, err);
        if (st == SL_OK)
            st = sl_scene_add_occluder(scene, mesh, NULL, B[0].object, err);
        if (st == SL_OK)
            *added = k;
    }
done:
    sl_free(c->a, pos, n * 24 * sizeof(float));
    sl_free(c->a, tri, n * 36 * sizeof(uint32_t));
    return st;
}

sl_status sl_synth_occluders(sl_scene scene, const sl_synth_options *opt, const sl_allocator *alloc,
                             sl_synth_stats *stats, sl_error *err)
{
    sl_synth_stats local;
    sl_synth_stats *s = stats ? stats : &local;
    memset(s, 0, sizeof *s);
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder synthesis: no scene");
    double t0 = thread_seconds(), w0 = sl_now();
    ctx c;
    memset(&c, 0, sizeof c);
    c.a = sl_alloc_or_default(alloc);
    c.opt = opt ? *opt : sl_synth_defaults();
    c.st = s;
    if (!(c.opt.voxel >= 0) || !(c.opt.min_box >= 0) || !(c.opt.weld >= 0) || !isfinite(c.opt.voxel) ||
        !isfinite(c.opt.min_box) || !isfinite(c.opt.weld))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder synthesis: voxel, min_box and weld must be finite and >= 0");
    uint32_t no = sl_scene_object_count(scene);
    sl_aabb sb = sl_scene_bounds(scene);
    double diag = no ? sqrt((double)(sb.max.x - sb.min.x) * (sb.max.x - sb.min.x) +
                            (double)(sb.max.y - sb.min.y) * (sb.max.y - sb.min.y) +
                            (double)(sb.max.z - sb.min.z) * (sb.max.z - sb.min.z))
                     : 0;
    double mag = no ? fmax(fmax(fabs(sb.min.x), fabs(sb.max.x)), fmax(fmax(fabs(sb.min.y), fabs(sb.max.y)),
                                                                      fmax(fabs(sb.min.z), fabs(sb.max.z))))
                    : 0;
    c.weld = c.opt.weld > 0 ? c.opt.weld : fmax(1e-6 * diag, 1e-9);
    /* the margin covers the weld (a vertex moves by at most sqrt(3) weld), float rounding of the
     * renderer's transform, and the test's own rounding */
    c.margin = 2.0 * c.weld + 4e-7 * mag + 1e-7 * diag;
    uint8_t *native = sl_calloc(c.a, no ? no : 1, 1);
    if (!native)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory");
    for (uint32_t i = 0; i < sl_scene_footprint_count(scene); i++) {
        uint32_t o = sl_scene_footprint(scene, i).object;
        if (o < no)
            native[o] = 1;
    }
    for (uint32_t i = 0; i < sl_scene_occluder_count(scene); i++) {
        uint32_t o = sl_scene_occluder(scene, i).object;
        if (o < no)
            native[o] = 1;
    }
    sl_status st = SL_OK;
    for (uint32_t o = 0; o < no && st == SL_OK; o++) {
        sl_object_view ov = sl_scene_object(scene, o);
        if (ov.flags & SL_OBJECT_SEE_THROUGH) {
            s->see_through++;
            continue;
        }
        if (native[o] || (ov.flags & SL_OBJECT_OCCLUDER)) {
            s->native++;
            continue;
        }
        if (ov.flags & SL_OBJECT_DYNAMIC) {
            s->dynamic++;
            continue;
        }
        s->considered++;
        wmesh w;
        st = weld_object(&c, scene, o, &w, err);
        if (st != SL_OK)
            break;
        uint32_t dropped = 0;
        int closed = keep_closed_parts(&c, &w, c.weld, &dropped);
        if (closed < 0) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder synthesis: out of memory");
        } else if (closed == 0) {
            s->open++;
        } else {
            s->closed++;
            s->base_open += closed == 2;
            s->partial += dropped > 0;
            c.base = closed == 2;
            c.base_z = w.lo.z;
            s->closed_volume += mesh_volume(&w);
            size_t before = c.boxes.count;
            st = synth_object(&c, &w, o, diag, err);
            if (st == SL_OK && c.boxes.count > before)
                s->objects_with_boxes++;
        }
        wmesh_free(&c, scene, o, &w);
    }
    sl_free(c.a, native, no ? no : 1);
    if (st == SL_OK) {
        cbox *B = c.boxes.data;
        size_t nb = c.boxes.count;
        uint32_t budget = c.opt.max_boxes ? c.opt.max_boxes : SYNTH_DEFAULT_PER_SCENE;
        if (nb > budget) {
            qsort(B, nb, sizeof *B, cbox_cmp_scene);
            nb = budget;
            qsort(B, nb, sizeof *B, cbox_cmp_object);
            s->dropped_by_budget = (uint32_t)(c.boxes.count - nb);
        }
        for (size_t i = 0; i < nb && st == SL_OK;) {
            size_t e = i;
            while (e < nb && B[e].object == B[i].object)
                e++;
            uint32_t added = 0;
            st = add_boxes(&c, scene, B + i, e - i, &added, err);
            if (added) {
                s->boxes += added;
                s->occluder_meshes++;
            }
            i = e;
        }
        if (st == SL_OK && s->boxes) {
            char buf[32];
            snprintf(buf, sizeof buf, "%u", s->boxes);
            st = sl_scene_set_meta(scene, "occluders.synthesised", buf, err);
        }
    }
    sl_array_free(c.a, &c.boxes, sizeof(cbox));
    s->volume_fraction = s->closed_volume > 0 ? s->covered_volume / s->closed_volume : 0;
    s->cpu_seconds = thread_seconds() - t0;
    s->seconds = sl_now() - w0;
    return st;
}

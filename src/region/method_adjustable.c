/* adjustable: from-region visibility by adjustable (angular) occluder shrinking.
 *
 * G. Koldas, "Efficient Visibility Estimation for Distributed Virtual Urban Environments", PhD
 * thesis, METU 2008, chapter 4 (section 4.1.2): instead of eroding occluders beforehand, the shadow
 * of each convex vertical prism seen from a point C is shrunk on the fly, in angles, so that what
 * it hides from C it hides from every point of the eps-disk around C: the azimuth interval loses
 * asin(eps/|CA|) at each silhouette vertex A (equations 4-6) and the elevation is taken as seen from
 * eps farther (occluder above the eye) or eps nearer (below it) (equations 9-16). The shrunk
 * shadows are fused in an occlusion horizon over the full 360 degrees of azimuth (the object-space
 * horizon of section 3.1.2). The visible set is valid for the whole disk; a view cell is covered
 * by disks (centres on a square grid of spacing eps*sqrt(2), whose squares the disks
 * circumscribe) and its set is the union over them. Eyes are at the cell's highest point (in 2.5D
 * what a lower eye sees a higher one sees too).
 *
 * The bounds used, per occluder piece P (convex, roof H) and disk (C, eps, eye height h), with A, B
 * the silhouette vertices of P from C and the chord AB inside P:
 *  - a point X at azimuth (from C) within the shrunk interval and farther than |CA|, |CB| + 2 eps
 *    lies behind chord AB from every eye E of the disk (the shrunk rays run parallel to the umbra
 *    boundaries of AB, eps inside them);
 *  - the sight line E->X crosses AB at a horizontal distance d_E <= max(|CA|,|CB|) + eps, and at
 *    least dist(C, AB) - eps; X is at r_E in [r_min - eps, r_max + eps];
 *  - hence X is hidden when (z - h) / (r_min - eps) <= (H - h) / (d_far + eps) for H > h, and when
 *    (z - h) / (r_max + eps) <= (H - h) / (d_near - eps) for H <= h (z: X's height). The horizon
 *    stores the right-hand sides per azimuth bin (max over pieces, only bins wholly inside a
 *    piece's shrunk interval), an object its left-hand side over every bin it touches.
 * A piece too close to the disk (a silhouette vertex or the chord within eps of C) contributes
 * nothing, like an occluder thinner than the shrinking.
 *
 * Footprints are split into convex pieces (GEOS triangulation, then triangles merged back while the
 * union stays convex — Hertel-Mehlhorn). Scope: PRISM and BOX cells of 2.5D scenes.
 *
 * Speed (adj_cell, filter_pieces): the disks are computed level by level, radius eps * 2^l from a
 * coarse level down to eps; a level's union is valid for the whole cell, so the cell's set may be
 * the intersection of the levels' unions, and each level only tests what the coarser one kept.
 * Per level, occluder pieces that cannot lie in front of any remaining candidate are left out —
 * any piece may be left out, since a lower horizon only makes a disk's set larger. */
#include "pvs_internal.h"

#include "geos_util.h"
#include "scene/scene_internal.h"

#include <math.h>
#include <stdlib.h>

#define TWO_PI (2.0 * M_PI)

typedef struct adj_config {
    float eps;
    uint32_t bins;
    uint32_t levels; /* coarser disk levels (radius eps * 2^l) that pre-filter the candidates */
} adj_config;

typedef struct piece {
    uint32_t first, count; /* vertices in xy, counter-clockwise, convex */
    double roof;
} piece;

typedef struct adj_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    adj_config cfg;
    uint32_t npiece;
    piece *pieces;
    double *xy;
    size_t nxy;
    uint32_t nobj;
    const sl_aabb *bounds;
} adj_shared;

/* A sort key: distance, then id (a total order: the result never depends on the sort). */
typedef struct keyed {
    double k;
    uint32_t id;
} keyed;

typedef struct adj_worker {
    adj_shared *sh;
    float *horizon;
    uint8_t *visible; /* per object, this level: seen by one of the level's disks */
    keyed *okey;      /* per live object: r_min, id */
    keyed *pkey;      /* per drawn piece: d_far, id */
    double *pdata;    /* per piece: lo, hi (azimuth), t (tangent bound) */
    uint32_t *live;   /* candidates not yet seen at this level */
    uint32_t *cand;   /* this level's candidates: the coarser level's set, ascending */
    uint32_t *plist;  /* pieces kept by the level's filter */
    double *need;     /* NEED_BINS: farthest candidate reach per azimuth (the piece filter) */
    sl_array centres; /* double[2]: the level's disk centres */
} adj_worker;

static const char g_help[] =
    "eps=FLOAT (default 0.7): radius of the disks whose sets are computed (metres); disks cover the cell on a "
    "grid of eps*sqrt(2)\n"
    "bins=2..65536 (default 2048): azimuth bins of the occlusion horizon\n"
    "levels=0..8 (default 8): at most this many coarser levels of disks (radius eps*2^l) whose sets bound the "
    "finer ones, stopping at the first whose single grid square covers the cell; 0: one level\n";

static sl_status adj_configure(sl_opts *o, void *config, sl_error *err)
{
    adj_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "eps", 0.7f, 0.05f, 1000.0f, &c->eps, err)) != SL_OK ||
        (st = sl_opts_u32(o, "bins", 2048, 2, 65536, &c->bins, err)) != SL_OK ||
        (st = sl_opts_u32(o, "levels", 8, 0, 8, &c->levels, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void adj_release(void *p)
{
    adj_shared *s = p;
    if (!s)
        return;
    sl_free(&s->a, s->pieces, ((size_t)s->npiece + 1) * sizeof(piece));
    sl_free(&s->a, s->xy, (s->nxy + 1) * sizeof(double));
    sl_free(&s->a, s, sizeof *s);
}

/* ---- convex decomposition ---- */

typedef struct poly_list {
    sl_array v;    /* double pairs */
    sl_array off;  /* uint32 first, count pairs */
} poly_list;

static bool convex_ccw(const double *p, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        const double *a = p + 2 * i, *b = p + 2 * ((i + 1) % n), *c = p + 2 * ((i + 2) % n);
        if (sl_orient2d(a[0], a[1], b[0], b[1], c[0], c[1]) < 0)
            return false;
    }
    return true;
}

/* Merge two CCW convex polygons sharing edge (p[i], p[i+1]) = (q[j+1], q[j]) into out; false when
 * the union is not convex. */
static bool try_merge(const double *p, uint32_t np, const double *q, uint32_t nq, double *out, uint32_t *nout)
{
    for (uint32_t i = 0; i < np; i++) {
        const double *a = p + 2 * i, *b = p + 2 * ((i + 1) % np);
        for (uint32_t j = 0; j < nq; j++) {
            const double *c = q + 2 * j, *d = q + 2 * ((j + 1) % nq);
            if (!(a[0] == d[0] && a[1] == d[1] && b[0] == c[0] && b[1] == c[1]))
                continue;
            /* p from b around to a, then q from a (= d) around to b (= c), skipping the shared edge */
            uint32_t n = 0;
            for (uint32_t k = 0; k < np - 1; k++) {
                const double *v = p + 2 * ((i + 1 + k) % np);
                out[2 * n] = v[0], out[2 * n + 1] = v[1], n++;
            }
            for (uint32_t k = 0; k < nq - 2; k++) {
                const double *v = q + 2 * ((j + 2 + k) % nq);
                out[2 * n] = v[0], out[2 * n + 1] = v[1], n++;
            }
            *nout = n;
            return convex_ccw(out, n);
        }
    }
    return false;
}

typedef struct tri_collect {
    sl_geos *g;
    const sl_allocator *a;
    sl_array tris; /* double[6], CCW */
    double *buf;
    size_t cap;
    bool oom;
} tri_collect;

static bool collect_tri(void *user, const GEOSGeometry *poly)
{
    tri_collect *t = user;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(t->g->h, poly);
    int n = ring ? sl_geos_ring_coords(t->g, ring, t->a, &t->buf, &t->cap) : -1;
    if (n != 3) {
        t->oom = n < 0;
        return n >= 0;
    }
    double tri[6];
    memcpy(tri, t->buf, sizeof tri);
    double o = sl_orient2d(tri[0], tri[1], tri[2], tri[3], tri[4], tri[5]);
    if (o == 0)
        return true;
    if (o < 0) {
        double x = tri[2], y = tri[3];
        tri[2] = tri[4], tri[3] = tri[5], tri[4] = x, tri[5] = y;
    }
    if (!sl_array_push(t->a, &t->tris, sizeof tri, tri, 1))
        t->oom = true;
    return !t->oom;
}

/* Convex pieces of one footprint appended to s (Hertel-Mehlhorn over GEOS's triangulation). */
static sl_status decompose(adj_shared *s, sl_geos *g, uint32_t f, sl_array *pieces, sl_array *xy, sl_error *err)
{
    sl_footprint_view fp = sl_scene_footprint(s->scene, f);
    double *ring = sl_alloc(&s->a, 2 * (size_t)fp.vertex_count * sizeof(double));
    if (!ring)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    for (uint32_t i = 0; i < 2 * fp.vertex_count; i++)
        ring[i] = fp.xy[i];
    sl_status st = SL_OK;
    if (convex_ccw(ring, fp.vertex_count)) {
        piece pc = {(uint32_t)(xy->count / 2), fp.vertex_count, fp.roof_z};
        if (!sl_array_push(&s->a, xy, sizeof(double), ring, 2 * (size_t)fp.vertex_count) ||
            !sl_array_push(&s->a, pieces, sizeof pc, &pc, 1))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
        sl_free(&s->a, ring, 2 * (size_t)fp.vertex_count * sizeof(double));
        return st;
    }
    sl_free(&s->a, ring, 2 * (size_t)fp.vertex_count * sizeof(double));
    GEOSGeometry *poly = sl_geos_polygon(g, fp.xy, fp.vertex_count);
    GEOSGeometry *tris = poly ? GEOSConstrainedDelaunayTriangulation_r(g->h, poly) : NULL;
    if (poly)
        GEOSGeom_destroy_r(g->h, poly);
    if (!tris)
        return sl_fail(err, SL_ERROR_INTERNAL, "adjustable: GEOS could not triangulate footprint %u: %s", f, g->message);
    tri_collect tc;
    memset(&tc, 0, sizeof tc);
    tc.g = g;
    tc.a = &s->a;
    sl_geos_each_polygon(g, tris, collect_tri, &tc);
    GEOSGeom_destroy_r(g->h, tris);
    sl_free(&s->a, tc.buf, tc.cap * sizeof(double));
    if (tc.oom) {
        sl_array_free(&s->a, &tc.tris, 6 * sizeof(double));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    /* polygons as fixed-size slots of up to 64 vertices; merge greedily, in order */
    uint32_t nt = (uint32_t)tc.tris.count;
    const uint32_t maxv = 64;
    double *slot = sl_alloc(&s->a, ((size_t)nt + 1) * maxv * 2 * sizeof(double));
    uint32_t *cnt = sl_calloc(&s->a, (size_t)nt + 1, sizeof(uint32_t));
    double tmp[2 * 64];
    if (!slot || !cnt) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    } else {
        for (uint32_t t = 0; t < nt; t++) {
            memcpy(slot + (size_t)t * maxv * 2, (double *)tc.tris.data + 6 * (size_t)t, 6 * sizeof(double));
            cnt[t] = 3;
        }
        for (bool merged = true; merged;) {
            merged = false;
            for (uint32_t i = 0; i < nt; i++)
                for (uint32_t j = i + 1; cnt[i] && j < nt; j++) {
                    uint32_t n;
                    if (!cnt[j] || cnt[i] + cnt[j] - 2 > maxv)
                        continue;
                    if (try_merge(slot + (size_t)i * maxv * 2, cnt[i], slot + (size_t)j * maxv * 2, cnt[j], tmp, &n)) {
                        memcpy(slot + (size_t)i * maxv * 2, tmp, 2 * (size_t)n * sizeof(double));
                        cnt[i] = n;
                        cnt[j] = 0;
                        merged = true;
                    }
                }
        }
        for (uint32_t t = 0; t < nt && st == SL_OK; t++) {
            if (!cnt[t])
                continue;
            piece pc = {(uint32_t)(xy->count / 2), cnt[t], fp.roof_z};
            if (!sl_array_push(&s->a, xy, sizeof(double), slot + (size_t)t * maxv * 2, 2 * (size_t)cnt[t]) ||
                !sl_array_push(&s->a, pieces, sizeof pc, &pc, 1))
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
        }
    }
    sl_free(&s->a, slot, ((size_t)nt + 1) * maxv * 2 * sizeof(double));
    sl_free(&s->a, cnt, ((size_t)nt + 1) * sizeof(uint32_t));
    sl_array_free(&s->a, &tc.tris, 6 * sizeof(double));
    return st;
}

static sl_status adj_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                             uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads; /* serial */
    adj_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->cfg = *(const adj_config *)config;
    s->nobj = sl_scene_object_count(scene);
    s->bounds = sl_scene_object_bounds_array(scene);
    *removed = 0;
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        if (vc[i].shape != SL_CELL_PRISM && vc[i].shape != SL_CELL_BOX) {
            adj_release(s);
            return sl_fail(err, SL_ERROR_UNSUPPORTED,
                           "adjustable: view cell %u is a BSP cluster; the method needs prism or box cells of a 2.5D "
                           "scene",
                           i);
        }
    sl_geos g;
    if (!sl_geos_init(&g)) {
        adj_release(s);
        return sl_fail(err, SL_ERROR_INTERNAL, "adjustable: GEOS could not start");
    }
    sl_array pieces = {0}, xy = {0};
    sl_status st = SL_OK;
    for (uint32_t f = 0; f < sl_scene_footprint_count(scene) && st == SL_OK; f++)
        st = decompose(s, &g, f, &pieces, &xy, err);
    sl_geos_finish(&g);
    if (st != SL_OK) {
        sl_array_free(alloc, &pieces, sizeof(piece));
        sl_array_free(alloc, &xy, sizeof(double));
        adj_release(s);
        return st;
    }
    s->npiece = (uint32_t)pieces.count;
    s->nxy = xy.count;
    s->pieces = sl_realloc(alloc, pieces.data, pieces.cap * sizeof(piece), ((size_t)s->npiece + 1) * sizeof(piece));
    s->xy = sl_realloc(alloc, xy.data, xy.cap * sizeof(double), (s->nxy + 1) * sizeof(double));
    if (!s->pieces || !s->xy) {
        if (!s->pieces)
            sl_array_free(alloc, &pieces, sizeof(piece));
        if (!s->xy)
            sl_array_free(alloc, &xy, sizeof(double));
        adj_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    *shared = s;
    return SL_OK;
}

static inline bool kless(const keyed *a, const keyed *b) { return a->k < b->k || (a->k == b->k && a->id < b->id); }

static inline void kswap(keyed *a, keyed *b)
{
    keyed t = *a;
    *a = *b;
    *b = t;
}

/* In-place quicksort by (k, id). glibc's qsort allocates a buffer as large as the array on every
 * call (page faults on fresh memory for 30,000 objects); this one allocates nothing. */
static void sort_keyed(keyed *v, size_t n)
{
    while (n > 16) {
        keyed *a = v, *b = v + n / 2, *c = v + n - 1;
        if (kless(b, a))
            kswap(a, b);
        if (kless(c, b))
            kswap(b, c);
        if (kless(b, a))
            kswap(a, b);
        keyed p = *b;
        ptrdiff_t i = -1, j = (ptrdiff_t)n;
        for (;;) {
            do
                i++;
            while (kless(&v[i], &p));
            do
                j--;
            while (kless(&p, &v[j]));
            if (i >= j)
                break;
            kswap(&v[i], &v[j]);
        }
        /* Hoare: [0, j] and [j+1, n), both non-empty; recurse on the smaller side */
        size_t left = (size_t)j + 1;
        if (left < n - left) {
            sort_keyed(v, left);
            v += left;
            n -= left;
        } else {
            sort_keyed(v + left, n - left);
            n = left;
        }
    }
    for (size_t i = 1; i < n; i++)
        for (size_t j = i; j > 0 && kless(&v[j], &v[j - 1]); j--)
            kswap(&v[j], &v[j - 1]);
}

#define NEED_BINS 720u /* azimuth bins of the per-level piece filter */

static void adj_worker_destroy(void *p)
{
    adj_worker *w = p;
    if (!w)
        return;
    const sl_allocator *a = &w->sh->a;
    size_t no = (size_t)w->sh->nobj + 1, np = (size_t)w->sh->npiece + 1;
    sl_free(a, w->horizon, (size_t)w->sh->cfg.bins * sizeof(float));
    sl_free(a, w->visible, no);
    sl_free(a, w->okey, no * sizeof(keyed));
    sl_free(a, w->pkey, np * sizeof(keyed));
    sl_free(a, w->pdata, 3 * np * sizeof(double));
    sl_free(a, w->live, no * sizeof(uint32_t));
    sl_free(a, w->cand, no * sizeof(uint32_t));
    sl_free(a, w->plist, np * sizeof(uint32_t));
    sl_free(a, w->need, NEED_BINS * sizeof(double));
    sl_array_free(a, &w->centres, 2 * sizeof(double));
    sl_free(a, w, sizeof *w);
}

static sl_status adj_worker_create(void *shared, void **out, sl_error *err)
{
    adj_shared *s = shared;
    adj_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    w->sh = s;
    size_t no = (size_t)s->nobj + 1, np = (size_t)s->npiece + 1;
    w->horizon = sl_alloc(&s->a, (size_t)s->cfg.bins * sizeof(float));
    w->visible = sl_alloc(&s->a, no);
    w->okey = sl_alloc(&s->a, no * sizeof(keyed));
    w->pkey = sl_alloc(&s->a, np * sizeof(keyed));
    w->pdata = sl_alloc(&s->a, 3 * np * sizeof(double));
    w->live = sl_alloc(&s->a, no * sizeof(uint32_t));
    w->cand = sl_alloc(&s->a, no * sizeof(uint32_t));
    w->plist = sl_alloc(&s->a, np * sizeof(uint32_t));
    w->need = sl_alloc(&s->a, NEED_BINS * sizeof(double));
    if (!w->horizon || !w->visible || !w->okey || !w->pkey || !w->pdata || !w->live || !w->cand || !w->plist ||
        !w->need) {
        adj_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    *out = w;
    return SL_OK;
}

/* Angular interval [*lo, *hi] (lo in [0, 2pi), hi - lo < pi) of points seen from c, and the
 * points at its ends; false when c is not clearly outside their hull (some point is not in front
 * of c relative to the points' mean direction, or c lies on one of them). The points all lie in
 * the open half-plane in front of c, where the cross product orders directions by angle, so the
 * two extremes come from orientation tests and only they need an atan2. */
static bool azimuth_range(double cx, double cy, const double *p, uint32_t n, double *lo, double *hi, uint32_t *ilo,
                          uint32_t *ihi)
{
    double mx = 0, my = 0;
    for (uint32_t i = 0; i < n; i++)
        mx += p[2 * i] - cx, my += p[2 * i + 1] - cy;
    uint32_t a = 0, b = 0;
    double ax = 0, ay = 0, bx = 0, by = 0;
    for (uint32_t i = 0; i < n; i++) {
        double dx = p[2 * i] - cx, dy = p[2 * i + 1] - cy;
        if (!(mx * dx + my * dy > 0))
            return false;
        if (i == 0) {
            ax = bx = dx, ay = by = dy;
            continue;
        }
        if (ax * dy - ay * dx < 0) /* clockwise of the lowest so far */
            a = i, ax = dx, ay = dy;
        if (bx * dy - by * dx > 0) /* counter-clockwise of the highest so far */
            b = i, bx = dx, by = dy;
    }
    double span = atan2(ax * by - ay * bx, ax * bx + ay * by);
    if (!(span >= 0 && span < M_PI - 1e-9))
        return false;
    double l = atan2(ay, ax);
    if (l < 0)
        l += TWO_PI;
    if (!(l < TWO_PI))
        l = 0;
    *lo = l;
    *hi = l + span;
    *ilo = a;
    *ihi = b;
    return true;
}

/* One disk of radius eps around (cx, cy) at eye height h: mark visible every live object it sees,
 * with the pieces plist[0..npl) as occluders. Leaving pieces out only lowers the horizon, so any
 * subset of the pieces gives a superset of the disk's set (still conservative). */
static void disk(adj_worker *w, double cx, double cy, double h, double eps, uint32_t nlive, uint32_t npl)
{
    adj_shared *s = w->sh;
    const uint32_t nb = s->cfg.bins;
    const double bw = TWO_PI / nb;
    keyed *pkey = w->pkey, *okey = w->okey;
    for (uint32_t b = 0; b < nb; b++)
        w->horizon[b] = -INFINITY;
    /* occluder pieces: shrunk intervals and tangent bounds, sorted by the far distance */
    uint32_t np = 0;
    for (uint32_t q = 0; q < npl; q++) {
        uint32_t k = w->plist[q];
        const piece *pc = &s->pieces[k];
        const double *v = s->xy + 2 * (size_t)pc->first;
        double lo, hi;
        uint32_t ia, ib;
        if (!azimuth_range(cx, cy, v, pc->count, &lo, &hi, &ia, &ib))
            continue;
        const double *A = v + 2 * ia, *B = v + 2 * ib;
        double ca = hypot(A[0] - cx, A[1] - cy), cb = hypot(B[0] - cx, B[1] - cy);
        double ab = hypot(B[0] - A[0], B[1] - A[1]);
        if (!(ca > eps) || !(cb > eps) || !(ab > 0))
            continue;
        /* distance from C to the chord (segment) AB */
        double t = ((cx - A[0]) * (B[0] - A[0]) + (cy - A[1]) * (B[1] - A[1])) / (ab * ab);
        t = fmin(1.0, fmax(0.0, t));
        double dnear = hypot(A[0] + t * (B[0] - A[0]) - cx, A[1] + t * (B[1] - A[1]) - cy);
        double dline = fabs(sl_orient2d(A[0], A[1], B[0], B[1], cx, cy)) / ab;
        if (!(dline > eps))
            continue;
        lo += asin(eps / ca);
        hi -= asin(eps / cb);
        if (!(hi > lo))
            continue;
        double dfar = fmax(ca, cb);
        double tb = pc->roof > h ? (pc->roof - h) / (dfar + eps) : (pc->roof - h) / (dnear - eps);
        pkey[np].k = dfar;
        pkey[np].id = k;
        w->pdata[3 * (size_t)k] = lo;
        w->pdata[3 * (size_t)k + 1] = hi;
        w->pdata[3 * (size_t)k + 2] = tb;
        np++;
    }
    sort_keyed(pkey, np);
    /* live objects sorted by their nearest distance */
    for (uint32_t i = 0; i < nlive; i++) {
        const sl_aabb *b = &s->bounds[w->live[i]];
        double dx = fmax(0.0, fmax(b->min.x - cx, cx - b->max.x)), dy = fmax(0.0, fmax(b->min.y - cy, cy - b->max.y));
        okey[i].k = hypot(dx, dy);
        okey[i].id = w->live[i];
    }
    sort_keyed(okey, nlive);
    uint32_t next = 0;
    for (uint32_t i = 0; i < nlive; i++) {
        double rmin = okey[i].k;
        uint32_t o = okey[i].id;
        if (w->visible[o])
            continue;
        /* pieces wholly nearer than the object (with the disk's slack) join the horizon */
        while (next < np && pkey[next].k + 2 * eps <= rmin - 1e-9) {
            uint32_t k = pkey[next].id;
            double lo = w->pdata[3 * (size_t)k], hi = w->pdata[3 * (size_t)k + 1];
            float tb = (float)w->pdata[3 * (size_t)k + 2];
            /* bins wholly inside [lo, hi] (hi may pass 2 pi: wrap) */
            int64_t b0 = (int64_t)ceil(lo / bw - 1e-12), b1 = (int64_t)floor(hi / bw + 1e-12) - 1;
            /* b0 >= 0 and b1 < 2 nb (lo < 2 pi + pi/2, hi - lo < pi): one subtraction wraps */
            for (int64_t b = b0; b <= b1; b++) {
                float *hz = &w->horizon[b >= (int64_t)nb ? b - nb : b];
                if (tb > *hz)
                    *hz = tb;
            }
            next++;
        }
        const sl_aabb *b = &s->bounds[o];
        double corners[8] = {b->min.x, b->min.y, b->max.x, b->min.y, b->max.x, b->max.y, b->min.x, b->max.y};
        double lo, hi;
        uint32_t ia, ib;
        if (!(rmin > eps) || !azimuth_range(cx, cy, corners, 4, &lo, &hi, &ia, &ib)) {
            w->visible[o] = 1;
            continue;
        }
        double top = b->max.z, tobj;
        if (top > h) {
            tobj = (top - h) / (rmin - eps);
        } else {
            double fx = fmax(fabs(b->min.x - cx), fabs(b->max.x - cx)), fy = fmax(fabs(b->min.y - cy), fabs(b->max.y - cy));
            tobj = (top - h) / (hypot(fx, fy) + eps);
        }
        /* every bin the object's interval touches must hide it */
        int64_t b0 = (int64_t)floor(lo / bw), b1 = (int64_t)floor(hi / bw);
        bool hidden = true;
        for (int64_t q = b0; q <= b1 && hidden; q++)
            hidden = (double)w->horizon[q >= (int64_t)nb ? q - nb : q] >= tobj;
        if (!hidden)
            w->visible[o] = 1;
    }
}

/* Does the square [x, x1] x [y, y1] meet the convex counter-clockwise polygon (separating axes)? */
static bool square_meets_poly(const double *poly, int n, double x, double y, double x1, double y1)
{
    double px0 = INFINITY, px1 = -INFINITY, py0 = INFINITY, py1 = -INFINITY;
    for (int i = 0; i < n; i++) {
        px0 = fmin(px0, poly[2 * i]), px1 = fmax(px1, poly[2 * i]);
        py0 = fmin(py0, poly[2 * i + 1]), py1 = fmax(py1, poly[2 * i + 1]);
    }
    if (px1 < x || px0 > x1 || py1 < y || py0 > y1)
        return false;
    const double sq[4][2] = {{x, y}, {x1, y}, {x1, y1}, {x, y1}};
    for (int i = 0; i < n; i++) {
        const double *a = poly + 2 * i, *b = poly + 2 * ((i + 1) % n);
        bool out_all = true;
        for (int c = 0; c < 4 && out_all; c++)
            out_all = sl_orient2d(a[0], a[1], b[0], b[1], sq[c][0], sq[c][1]) < 0;
        if (out_all)
            return false;
    }
    return true;
}

/* Mark bins [lo, hi] (radians, hi may pass 2 pi) of a NEED_BINS circle with max(need, v). */
static void need_mark(double *need, double lo, double hi, double v)
{
    const double bw = TWO_PI / NEED_BINS;
    int64_t b0 = (int64_t)floor(lo / bw), b1 = (int64_t)floor(hi / bw);
    if (b1 - b0 >= (int64_t)NEED_BINS)
        b1 = b0 + NEED_BINS - 1;
    for (int64_t b = b0; b <= b1; b++) {
        double *n = &need[((b % NEED_BINS) + NEED_BINS) % NEED_BINS];
        if (v > *n)
            *n = v;
    }
}

/* The pieces worth drawing for the disks centred within rc of (ox, oy), given the candidate
 * objects cand[0..nc): a piece is kept when, in some direction where it lies, a candidate lies
 * farther. Both azimuth intervals are widened by what moving the eye rc can change them
 * (asin(rc / distance)), distances are moved by rc. This is a speed filter only: a piece left out
 * lowers the horizon, which can only make a disk's set larger, never smaller. */
static uint32_t filter_pieces(adj_worker *w, double ox, double oy, double rc, double eps, uint32_t nc)
{
    adj_shared *s = w->sh;
    double *need = w->need, all = -INFINITY;
    for (uint32_t b = 0; b < NEED_BINS; b++)
        need[b] = -INFINITY;
    for (uint32_t i = 0; i < nc; i++) {
        const sl_aabb *b = &s->bounds[w->cand[i]];
        double dx = fmax(0.0, fmax(b->min.x - ox, ox - b->max.x)), dy = fmax(0.0, fmax(b->min.y - oy, oy - b->max.y));
        double d = hypot(dx, dy), reach = d + rc;
        double corners[8] = {b->min.x, b->min.y, b->max.x, b->min.y, b->max.x, b->max.y, b->min.x, b->max.y};
        double lo, hi;
        uint32_t ia, ib;
        if (!(d > 2 * rc) || !azimuth_range(ox, oy, corners, 4, &lo, &hi, &ia, &ib)) {
            all = fmax(all, reach);
            continue;
        }
        double widen = asin(rc / d);
        need_mark(need, lo - widen + TWO_PI, hi + widen + TWO_PI, reach);
    }
    uint32_t npl = 0;
    for (uint32_t k = 0; k < s->npiece; k++) {
        const piece *pc = &s->pieces[k];
        const double *v = s->xy + 2 * (size_t)pc->first;
        double near = INFINITY;
        for (uint32_t i = 0; i < pc->count; i++)
            near = fmin(near, hypot(v[2 * i] - ox, v[2 * i + 1] - oy));
        /* the pieces' nearest point may be on an edge: the vertices' minimum is within the
         * piece's own extent of it, so only a lower bound is wanted here: use the box distance */
        double px0 = INFINITY, px1 = -INFINITY, py0 = INFINITY, py1 = -INFINITY;
        for (uint32_t i = 0; i < pc->count; i++) {
            px0 = fmin(px0, v[2 * i]), px1 = fmax(px1, v[2 * i]);
            py0 = fmin(py0, v[2 * i + 1]), py1 = fmax(py1, v[2 * i + 1]);
        }
        double dx = fmax(0.0, fmax(px0 - ox, ox - px1)), dy = fmax(0.0, fmax(py0 - oy, oy - py1));
        double dbox = hypot(dx, dy);
        /* a piece joins an object's horizon only when nearer than it by 2 eps (disk()) */
        double reach = fmax(0.0, dbox - rc) + 2 * eps;
        bool keep = all >= reach;
        double lo, hi;
        uint32_t ia, ib;
        if (!keep && (!(dbox > 2 * rc) || !azimuth_range(ox, oy, v, pc->count, &lo, &hi, &ia, &ib)))
            keep = true;
        if (!keep) {
            double widen = asin(rc / fmin(near, fmax(dbox, 2 * rc)));
            const double bw = TWO_PI / NEED_BINS;
            int64_t b0 = (int64_t)floor((lo - widen + TWO_PI) / bw), b1 = (int64_t)floor((hi + widen + TWO_PI) / bw);
            for (int64_t b = b0; b <= b1 && !keep; b++)
                keep = need[b % NEED_BINS] >= reach;
        }
        if (keep)
            w->plist[npl++] = k;
    }
    return npl;
}

/* Disk centres of one level: the centres of the grid squares (side eps*sqrt(2), circumradius eps,
 * anchored at the cell box's corner) that meet the cell's polygon; they cover the cell. */
static bool level_centres(adj_worker *w, const double *poly, int n, const sl_aabb *bb, double eps)
{
    const double side = eps * M_SQRT2;
    w->centres.count = 0;
    for (double y = bb->min.y; y < bb->max.y + 1e-9 || y == bb->min.y; y += side)
        for (double x = bb->min.x; x < bb->max.x + 1e-9 || x == bb->min.x; x += side) {
            if (!square_meets_poly(poly, n, x, y, x + side, y + side))
                continue;
            double c[2] = {x + 0.5 * side, y + 0.5 * side};
            if (!sl_array_push(&w->sh->a, &w->centres, sizeof c, c, 1))
                return false;
        }
    return true;
}

/* The cell's set is computed level by level (hierarchical disks): level l covers the cell with
 * disks of radius eps * 2^l, coarsest first. The union of a level's disk sets is conservative for
 * the cell (the disks cover it, each set is valid in its disk), so the intersection of the levels'
 * unions is conservative too; each level therefore only tests the objects that the coarser level
 * kept. With levels=0 this is the plain method. */
static sl_status adj_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    adj_worker *w = worker;
    adj_shared *s = w->sh;
    const sl_viewcell *vc = &sl_viewcells_data(s->cells)[cell];
    double poly[8];
    int n;
    if (vc->shape == SL_CELL_PRISM) {
        for (int i = 0; i < 3; i++)
            poly[2 * i] = vc->tri[i].x, poly[2 * i + 1] = vc->tri[i].y;
        n = 3;
    } else {
        const sl_aabb *b = &vc->bounds;
        double q[8] = {b->min.x, b->min.y, b->max.x, b->min.y, b->max.x, b->max.y, b->min.x, b->max.y};
        memcpy(poly, q, sizeof q);
        n = 4;
    }
    const sl_aabb *bb = &vc->bounds;
    uint32_t nc = s->nobj;
    for (uint32_t o = 0; o < s->nobj; o++)
        w->cand[o] = o;
    uint64_t work = 0;
    /* the coarsest level: the first whose single grid square covers the cell's box (a coarser one
     * would only repeat a full pass with a looser disk), at most cfg.levels */
    int top = 0;
    const double extent = fmax((double)bb->max.x - bb->min.x, (double)bb->max.y - bb->min.y);
    while (top < (int)s->cfg.levels && s->cfg.eps * ldexp(1.0, top) * M_SQRT2 < extent)
        top++;
    for (int level = top; level >= 0; level--) {
        const double eps = s->cfg.eps * ldexp(1.0, level);
        if (!level_centres(w, poly, n, bb, eps))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
        const double(*cen)[2] = w->centres.data;
        const size_t ncen = w->centres.count;
        /* pieces that can matter to this level's candidates, from the centres' mean */
        double ox = 0, oy = 0, rc = 0;
        for (size_t i = 0; i < ncen; i++)
            ox += cen[i][0], oy += cen[i][1];
        ox /= (double)ncen, oy /= (double)ncen;
        for (size_t i = 0; i < ncen; i++)
            rc = fmax(rc, hypot(cen[i][0] - ox, cen[i][1] - oy));
        rc = rc * (1 + 1e-9) + 1e-9;
        uint32_t npl = filter_pieces(w, ox, oy, rc, eps, nc);
        for (uint32_t i = 0; i < nc; i++)
            w->visible[w->cand[i]] = 0;
        for (size_t i = 0; i < ncen; i++) {
            uint32_t nlive = 0;
            for (uint32_t q = 0; q < nc; q++)
                if (!w->visible[w->cand[q]])
                    w->live[nlive++] = w->cand[q];
            if (nlive == 0)
                break;
            disk(w, cen[i][0], cen[i][1], vc->z_max, eps, nlive, npl);
            work++;
        }
        /* the next level's candidates: this level's union (cand stays ascending) */
        uint32_t m = 0;
        for (uint32_t q = 0; q < nc; q++)
            if (w->visible[w->cand[q]])
                w->cand[m++] = w->cand[q];
        nc = m;
    }
    memcpy(out->ids, w->cand, (size_t)nc * sizeof(uint32_t));
    out->count = nc;
    out->work = work;
    return SL_OK;
}

const sl_pvs_method sl_pvs_method_adjustable = {
    .name = "adjustable",
    .summary = "adjustable angular occluder shrinking in an occlusion horizon, sets valid in eps-disks that "
               "cover the cell (Koldas 2008, ch. 4); conservative for 2.5D scenes",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(adj_config),
    .configure = adj_configure,
    .prepare = adj_prepare,
    .worker_create = adj_worker_create,
    .cell = adj_cell,
    .worker_destroy = adj_worker_destroy,
    .release = adj_release,
    .notice = NULL,
};

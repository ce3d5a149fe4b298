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
 * what a lower eye sees a higher one sees too, for occluders standing on the ground: footprints
 * above it: "Footprints that do not reach down to the ground" below).
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
 * These are the thesis's bounds, for a piece's whole interval. run_chunks proves and uses tighter
 * ones per stretch of bins (split: d_far and d_near of the part of the chord within eps of the
 * stretch's wedge, and that far distance as the one an object must lie beyond) and for runs of
 * touching pieces as one occluder (fuse).
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

extern const sl_pvs_method sl_pvs_method_adjustable;

/* Length of (x, y): metres of a city, far from overflow, so no need for hypot's care (or cost). */
static inline double len2(double x, double y) { return sqrt(x * x + y * y); }

typedef struct adj_config {
    float eps;
    uint32_t bins;
    uint32_t levels; /* coarser disk levels (radius eps * 2^l) that pre-filter the candidates */
    float split;     /* a piece's horizon is cut where its distance grows by this factor; 0: not */
    bool fuse;       /* runs of touching pieces shrink only at their ends */
} adj_config;

typedef struct piece {
    uint32_t first, count; /* vertices in xy, counter-clockwise, convex */
    double roof;
    double base;           /* the footprint's base_z (see sl_cell_floor) */
} piece;

/* Two pieces whose boundaries share the stretch s (x0, y0, x1, y1). */
typedef struct touch {
    uint32_t from, to;
    double s[4];
} touch;

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
    uint32_t ntouch;       /* touching piece pairs, both ways */
    uint32_t *touch_start; /* per piece, its first pair in touches (npiece + 1) */
    touch *touches;        /* sorted by (from, to) */
    size_t touch_cap;
    double *edge_sc;   /* sin, cos of every bin edge's azimuth (bins + 1 pairs) */
    sl_base_levels bases; /* the scene's distinct footprint bases (sl_cell_floor) */
    uint32_t *low;     /* the objects whose box reaches below the highest base (lower_boxes) */
    uint32_t nlow;
    double log_split;  /* log(cfg.split) */
    /* the probe only (sl_adj_probe_*): the boxes tested, and a bucket grid of the pieces */
    sl_aabb *probe_boxes;
    uint32_t gnx, gny;
    double gx0, gy0, gcell;
    uint32_t *gstart, *gitems; /* per bucket its pieces: gitems[gstart[b] .. gstart[b + 1]) */
    size_t gcount;
} adj_shared;

/* A sort key: distance, then id (a total order: the result never depends on the sort). */
typedef struct keyed {
    double k;
    uint32_t id;
} keyed;

/* One stretch of an occluder piece's horizon: the bins [b0, b1] (b1 may pass the bin count: wrap)
 * hide what lies beyond the piece's chord in them, up to the tangent bound tb. */
typedef struct chunk {
    int64_t b0, b1;
    float tb;
} chunk;

/* A piece as one disk sees it: silhouette azimuths and vertices, and its place in a run. */
typedef struct pview {
    double lo, hi;
    double ab[4]; /* the silhouette vertices at lo and at hi */
    uint32_t stamp, succ, pred;
} pview;

#define MAX_CHUNKS 16
#define MAX_RUN (MAX_CHUNKS + 1) /* pieces in one run of touching pieces (a zone per joint) */

typedef struct adj_worker {
    adj_shared *sh;
    float *horizon;
    uint8_t *visible; /* per object, this level: seen by one of the level's disks */
    keyed *okey;      /* per live object: r_min, id */
    sl_array chunks;  /* chunk: the disk's horizon pieces (bin ranges of occluder pieces) */
    sl_array ckey;    /* keyed per chunk: the distance beyond which it hides, index */
    uint32_t *live;   /* candidates not yet seen at this level */
    uint32_t *cand;   /* this level's candidates: the coarser level's set, ascending */
    uint32_t *plist;  /* pieces kept by the level's filter */
    double *need;     /* NEED_BINS: farthest candidate reach per azimuth (the piece filter) */
    sl_array centres; /* double[2]: the level's disk centres */
    pview *view;      /* per piece, valid where stamp matches */
    uint32_t stamp;
    double runv[4 * MAX_RUN];  /* the polyline of the run being chunked */
    double runa[2 * MAX_RUN];  /* its vertices' azimuths from C (lifted) */
    double segw[2 * MAX_RUN];  /* run_chunks: per segment, the band's azimuth slack */
    uint32_t *pin, *pmark;     /* the probe (sl_adj_probe_*): gathered pieces, their marks */
    uint32_t pstamp;
    const sl_aabb *bounds;     /* the boxes tested: the objects', with lower_boxes' stand-ins */
    sl_aabb *wb;               /* the copy holding the stand-ins (when the shared low list is not empty) */
} adj_worker;

static const char g_help[] =
    "eps=FLOAT (default 0.7): radius of the disks whose sets are computed (metres); disks cover the cell on a "
    "grid of eps*sqrt(2)\n"
    "bins=2..65536 (default 8192): azimuth bins of the occlusion horizon\n"
    "levels=0..8 (default 8): at most this many coarser levels of disks (radius eps*2^l) whose sets bound the "
    "finer ones, stopping at the first whose single grid square covers the cell; 0: one level\n"
    "split=0 or 1.01..100 (default 1.1): a piece's stretch of horizon is cut into chunks, each with the tangent "
    "bound of its own part of the piece, where the distance of the piece grows by this factor (at most 16 "
    "chunks); 0: one bound per piece, from its farther silhouette vertex (the thesis)\n"
    "fuse=BOOL (default false): a run of touching pieces (footprints sharing a wall, parts of one footprint) "
    "is also drawn as one occluder, shrunk only at its two ends, around the joints where the pieces on their "
    "own leave gaps (vienna: 0.7% fewer objects for 20% more time)\n";

static sl_status adj_configure(sl_opts *o, void *config, sl_error *err)
{
    adj_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "eps", 0.7f, 0.05f, 1000.0f, &c->eps, err)) != SL_OK ||
        (st = sl_opts_u32(o, "bins", 8192, 2, 65536, &c->bins, err)) != SL_OK ||
        (st = sl_opts_u32(o, "levels", 8, 0, 8, &c->levels, err)) != SL_OK ||
        (st = sl_opts_float(o, "split", 1.1f, 0.0f, 100.0f, &c->split, err)) != SL_OK ||
        (st = sl_opts_bool(o, "fuse", false, &c->fuse, err)) != SL_OK)
        return st;
    if (c->split != 0 && !(c->split >= 1.01f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "adjustable: split must be 0 or at least 1.01 (got %g)",
                       (double)c->split);
    return SL_OK;
}

static void adj_release(void *p)
{
    adj_shared *s = p;
    if (!s)
        return;
    sl_free(&s->a, s->pieces, ((size_t)s->npiece + 1) * sizeof(piece));
    sl_free(&s->a, s->touch_start, s->touch_start ? ((size_t)s->npiece + 1) * sizeof(uint32_t) : 0);
    sl_free(&s->a, s->touches, s->touch_cap * sizeof(touch));
    sl_free(&s->a, s->edge_sc, s->edge_sc ? 2 * ((size_t)s->cfg.bins + 1) * sizeof(double) : 0);
    sl_base_levels_free(&s->bases, &s->a);
    sl_free(&s->a, s->low, s->low ? ((size_t)s->nobj + 1) * sizeof(uint32_t) : 0);
    sl_free(&s->a, s->xy, (s->nxy + 1) * sizeof(double));
    sl_free(&s->a, s->probe_boxes, s->probe_boxes ? ((size_t)s->nobj + 1) * sizeof(sl_aabb) : 0);
    sl_free(&s->a, s->gstart, s->gstart ? ((size_t)s->gnx * s->gny + 1) * sizeof(uint32_t) : 0);
    sl_free(&s->a, s->gitems, s->gitems ? (s->gcount + 1) * sizeof(uint32_t) : 0);
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
            /* p from b around to a (all np vertices), then q's vertices strictly between a (= d)
             * and b (= c) */
            uint32_t n = 0;
            for (uint32_t k = 0; k < np; k++) {
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
    if (sl_scene_footprint_moves(s->scene, f)) /* a moving object's footprint: never an occluder */
        return SL_OK;
    sl_footprint_view fp = sl_scene_footprint(s->scene, f);
    double *ring = sl_alloc(&s->a, 2 * (size_t)fp.vertex_count * sizeof(double));
    if (!ring)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    for (uint32_t i = 0; i < 2 * fp.vertex_count; i++)
        ring[i] = fp.xy[i];
    sl_status st = SL_OK;
    if (convex_ccw(ring, fp.vertex_count)) {
        piece pc = {(uint32_t)(xy->count / 2), fp.vertex_count, fp.roof_z, fp.base_z};
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
            piece pc = {(uint32_t)(xy->count / 2), cnt[t], fp.roof_z, fp.base_z};
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

/* ---- touching pieces (fusion) ---- */

/* Pieces that share a stretch of boundary: a sight line that crosses the chord of one and then
 * the chord of the other never leaves the union, so the horizon may treat a run of touching pieces
 * as one occluder, shrunk only at the run's two ends (see run_chunks). Edges within TOUCH_TOL of
 * each other's line count as touching: a slit narrower than that between two footprints is taken
 * as closed (fuse only; the default leaves fuse off). */
typedef struct bedge {
    uint32_t piece;
    double x0, y0, x1, y1;
} bedge;

#define TOUCH_TOL 1e-5 /* metres: an edge lies on another's line */
#define TOUCH_MIN 1e-3 /* metres: the shortest shared stretch that links two pieces */

/* The stretch that edges e and f share, if they are collinear and overlap by TOUCH_MIN or more. */
static bool shared_stretch(const bedge *e, const bedge *f, double s[4])
{
    double dx = e->x1 - e->x0, dy = e->y1 - e->y0, len = len2(dx, dy);
    if (!(len > TOUCH_MIN))
        return false;
    double ux = dx / len, uy = dy / len;
    /* distances of f's ends from e's line, and their positions along it */
    double d0 = (f->x0 - e->x0) * uy - (f->y0 - e->y0) * ux, d1 = (f->x1 - e->x0) * uy - (f->y1 - e->y0) * ux;
    if (!(fabs(d0) <= TOUCH_TOL && fabs(d1) <= TOUCH_TOL))
        return false;
    double p0 = (f->x0 - e->x0) * ux + (f->y0 - e->y0) * uy, p1 = (f->x1 - e->x0) * ux + (f->y1 - e->y0) * uy;
    double a = fmax(0.0, fmin(p0, p1)), b = fmin(len, fmax(p0, p1));
    if (!(b - a >= TOUCH_MIN))
        return false;
    s[0] = e->x0 + a * ux, s[1] = e->y0 + a * uy, s[2] = e->x0 + b * ux, s[3] = e->y0 + b * uy;
    return true;
}

static int cmp_link(const void *a, const void *b)
{
    const touch *x = a, *y = b;
    if (x->from != y->from)
        return x->from < y->from ? -1 : 1;
    if (x->to != y->to)
        return x->to < y->to ? -1 : 1;
    /* the longer stretch first, then by coordinates: a total order */
    double lx = len2(x->s[2] - x->s[0], x->s[3] - x->s[1]), ly = len2(y->s[2] - y->s[0], y->s[3] - y->s[1]);
    if (lx != ly)
        return lx > ly ? -1 : 1;
    return memcmp(x->s, y->s, sizeof x->s);
}

/* The touching pairs of s's pieces, both ways, sorted by (from, to), one per pair. Edges are
 * bucketed on a grid of TOUCH_CELL metres by their boxes. */
#define TOUCH_CELL 16.0
static sl_status find_touching(adj_shared *s, sl_error *err)
{
    const sl_allocator *a = &s->a;
    sl_array edges = {0}, links = {0};
    sl_status st = SL_OK;
    double gx0 = INFINITY, gy0 = INFINITY, gx1 = -INFINITY, gy1 = -INFINITY;
    for (uint32_t k = 0; k < s->npiece; k++) {
        const piece *pc = &s->pieces[k];
        const double *v = s->xy + 2 * (size_t)pc->first;
        for (uint32_t i = 0; i < pc->count; i++) {
            const double *p = v + 2 * i, *q = v + 2 * ((i + 1) % pc->count);
            bedge e = {k, p[0], p[1], q[0], q[1]};
            if (!sl_array_push(a, &edges, sizeof e, &e, 1))
                goto oom;
            gx0 = fmin(gx0, p[0]), gx1 = fmax(gx1, p[0]), gy0 = fmin(gy0, p[1]), gy1 = fmax(gy1, p[1]);
        }
    }
    size_t ne = edges.count;
    if (ne) {
        uint32_t nx = (uint32_t)fmin(4096.0, floor((gx1 - gx0) / TOUCH_CELL) + 1);
        uint32_t ny = (uint32_t)fmin(4096.0, floor((gy1 - gy0) / TOUCH_CELL) + 1);
        const bedge *ev = edges.data;
        /* counting sort of (cell, edge) entries */
        size_t ncell = (size_t)nx * ny;
        uint32_t *start = sl_calloc(a, ncell + 1, sizeof(uint32_t));
        uint32_t(*range)[4] = sl_alloc(a, ne * sizeof *range);
        if (!start || !range) {
            sl_free(a, start, (ncell + 1) * sizeof(uint32_t));
            sl_free(a, range, ne * sizeof *range);
            goto oom;
        }
        size_t total = 0;
        for (size_t i = 0; i < ne; i++) {
            const bedge *e = &ev[i];
            double x0 = fmin(e->x0, e->x1) - TOUCH_TOL, x1 = fmax(e->x0, e->x1) + TOUCH_TOL;
            double y0 = fmin(e->y0, e->y1) - TOUCH_TOL, y1 = fmax(e->y0, e->y1) + TOUCH_TOL;
            uint32_t r[4] = {(uint32_t)fmax(0.0, floor((x0 - gx0) / TOUCH_CELL)),
                             (uint32_t)fmax(0.0, floor((y0 - gy0) / TOUCH_CELL)),
                             (uint32_t)fmin(nx - 1.0, floor((x1 - gx0) / TOUCH_CELL)),
                             (uint32_t)fmin(ny - 1.0, floor((y1 - gy0) / TOUCH_CELL))};
            memcpy(range[i], r, sizeof r);
            for (uint32_t y = r[1]; y <= r[3]; y++)
                for (uint32_t x = r[0]; x <= r[2]; x++)
                    start[(size_t)y * nx + x + 1]++, total++;
        }
        for (size_t c = 0; c < ncell; c++)
            start[c + 1] += start[c];
        uint32_t *ids = sl_alloc(a, (total + 1) * sizeof(uint32_t));
        uint32_t *fill = sl_alloc(a, (ncell + 1) * sizeof(uint32_t));
        if (!ids || !fill) {
            sl_free(a, ids, (total + 1) * sizeof(uint32_t));
            sl_free(a, fill, (ncell + 1) * sizeof(uint32_t));
            sl_free(a, start, (ncell + 1) * sizeof(uint32_t));
            sl_free(a, range, ne * sizeof *range);
            goto oom;
        }
        memcpy(fill, start, (ncell + 1) * sizeof(uint32_t));
        for (size_t i = 0; i < ne; i++)
            for (uint32_t y = range[i][1]; y <= range[i][3]; y++)
                for (uint32_t x = range[i][0]; x <= range[i][2]; x++)
                    ids[fill[(size_t)y * nx + x]++] = (uint32_t)i;
        bool oom = false;
        for (size_t c = 0; c < ncell && !oom; c++)
            for (uint32_t i = start[c]; i < start[c + 1] && !oom; i++)
                for (uint32_t j = i + 1; j < start[c + 1] && !oom; j++) {
                    const bedge *e = &ev[ids[i]], *f = &ev[ids[j]];
                    double sh[4];
                    if (e->piece == f->piece || !shared_stretch(e, f, sh))
                        continue;
                    touch t1 = {e->piece, f->piece, {sh[0], sh[1], sh[2], sh[3]}};
                    touch t2 = {f->piece, e->piece, {sh[0], sh[1], sh[2], sh[3]}};
                    oom = !sl_array_push(a, &links, sizeof t1, &t1, 1) || !sl_array_push(a, &links, sizeof t2, &t2, 1);
                }
        sl_free(a, ids, (total + 1) * sizeof(uint32_t));
        sl_free(a, fill, (ncell + 1) * sizeof(uint32_t));
        sl_free(a, start, (ncell + 1) * sizeof(uint32_t));
        sl_free(a, range, ne * sizeof *range);
        if (oom)
            goto oom;
    }
    sl_array_free(a, &edges, sizeof(bedge));
    /* one link per ordered pair: the longest stretch */
    touch *tv = links.data;
    size_t nl = links.count, m = 0;
    if (nl)
        qsort(tv, nl, sizeof *tv, cmp_link);
    for (size_t i = 0; i < nl; i++)
        if (m == 0 || tv[m - 1].from != tv[i].from || tv[m - 1].to != tv[i].to)
            tv[m++] = tv[i];
    s->touch_start = sl_calloc(a, (size_t)s->npiece + 1, sizeof(uint32_t));
    if (!s->touch_start)
        goto oom;
    for (size_t i = 0; i < m; i++)
        s->touch_start[tv[i].from + 1]++;
    for (uint32_t k = 0; k < s->npiece; k++)
        s->touch_start[k + 1] += s->touch_start[k];
    s->ntouch = (uint32_t)m;
    s->touches = links.data;
    s->touch_cap = links.cap;
    return st;
oom:
    sl_array_free(a, &edges, sizeof(bedge));
    sl_array_free(a, &links, sizeof(touch));
    return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
}

/* Footprints that do not reach down to the ground. The horizon treats a piece as a wall from the
 * ground up to its roof (and the eyes at the cell's top as the ones that see most), which holds
 * only for sight lines that pass it above its base. Every sight line from an eye at height zE to
 * a point at height zX runs at or above min(zE, zX), so a piece of base B is safe for every line
 * from the cell to an object when B <= the cell's lowest eye and B <= the object's lowest point.
 * Per cell: zfloor, the lowest eye; the pieces used are those of base <= zfloor (a piece above
 * it, a bridge or an overhang the eye may pass under, hides nothing), and tb, the highest base
 * among them. An object whose box lies wholly above tb is tested as it is; one that reaches below
 * tb (a river in its bed) is tested through a stand-in box above tb (lower_boxes). In a city on
 * flat ground every base is 0 and tb = 0 (sl_cell_floor, base_levels.c). */
/* The objects whose box reaches below the highest piece base: the only ones lower_boxes may
 * replace. Called once the shared boxes are final. */
static bool find_low(adj_shared *s)
{
    sl_free(&s->a, s->low, s->low ? ((size_t)s->nobj + 1) * sizeof(uint32_t) : 0);
    s->low = NULL;
    s->nlow = 0;
    if (s->bases.n == 0)
        return true;
    const double top = sl_base_levels_top(&s->bases);
    if (!(s->low = sl_alloc(&s->a, ((size_t)s->nobj + 1) * sizeof(uint32_t))))
        return false;
    for (uint32_t o = 0; o < s->nobj; o++)
        if (s->bounds[o].min.z < top)
            s->low[s->nlow++] = o;
    return true;
}

/* Stand-ins for the objects reaching below tb, for one cell (zfloor, tb: sl_cell_floor). A point P
 * of the object below tb seen from an eye E of the cell (zE >= zfloor >= tb) is seen along a line
 * that crosses the plane z = tb at Q = E + t (P - E), t = (zE - tb) / (zE - zP), with the part
 * E -> Q free; t grows with zE and with zP, so t >= t0 = (zfloor - tb) / (zfloor - zmin).
 * Q lies in the box between the cell's box and the object's at some t in [t0, 1], hence in the
 * hull of those at t0 and at 1 (linear in t), at height tb. If P is seen, so is Q, and so is
 * the stand-in: that hull in x, y, from tb up to the object's top (which holds the part above tb
 * too). Every point of it lies at or above every used base, where the horizon's argument holds;
 * hiding it hides the object. With zfloor = tb, t0 = 0 and the stand-in holds the cell: seen. */
static void lower_boxes(adj_worker *w, const sl_viewcell *vc, double zfloor, double tb)
{
    const adj_shared *s = w->sh;
    for (uint32_t i = 0; i < s->nlow; i++) {
        const uint32_t o = s->low[i];
        const sl_aabb *b = &s->bounds[o];
        sl_aabb *q = &w->wb[o];
        if (!(b->min.z < tb)) {
            *q = *b;
            continue;
        }
        const double t0 = (zfloor - tb) / (zfloor - (double)b->min.z);
        const double c[4] = {vc->bounds.min.x, vc->bounds.min.y, vc->bounds.max.x, vc->bounds.max.y};
        const double x[4] = {b->min.x, b->min.y, b->max.x, b->max.y};
        float r[4];
        for (int k = 0; k < 4; k++) {
            double m = c[k] + t0 * (x[k] - c[k]); /* rounded outward below */
            r[k] = k < 2 ? (float)fmin(x[k], m - 1e-6 * (1 + fabs(m))) : (float)fmax(x[k], m + 1e-6 * (1 + fabs(m)));
        }
        *q = (sl_aabb){{r[0], r[1], (float)tb}, {r[2], r[3], fmaxf(b->max.z, (float)tb)}};
    }
}

/* The method's preparation over the footprints f with use[f] (all when use is NULL). */
static sl_status adj_prepare_some(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                                  const uint8_t *use, void **shared, uint64_t *removed, sl_error *err)
{
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
        if (!use || use[f])
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
    s->log_split = s->cfg.split > 0 ? log((double)s->cfg.split) : 0;
    s->edge_sc = sl_alloc(alloc, 2 * ((size_t)s->cfg.bins + 1) * sizeof(double));
    if (!s->edge_sc) {
        adj_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    for (uint32_t b = 0; b <= s->cfg.bins; b++) {
        double az = b * (TWO_PI / s->cfg.bins);
        s->edge_sc[2 * b] = sin(az), s->edge_sc[2 * b + 1] = cos(az);
    }
    if (!sl_base_levels_of_scene(&s->bases, scene, alloc)) {
        adj_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    if ((st = find_touching(s, err)) != SL_OK) {
        adj_release(s);
        return st;
    }
    if (!find_low(s)) {
        adj_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    *shared = s;
    return SL_OK;
}

static sl_status adj_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                             uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads; /* serial */
    return adj_prepare_some(scene, cells, config, alloc, NULL, shared, removed, err);
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
    sl_array_free(a, &w->chunks, sizeof(chunk));
    sl_free(a, w->view, np * sizeof(pview));
    sl_array_free(a, &w->ckey, sizeof(keyed));
    sl_free(a, w->live, no * sizeof(uint32_t));
    sl_free(a, w->cand, no * sizeof(uint32_t));
    sl_free(a, w->plist, np * sizeof(uint32_t));
    sl_free(a, w->need, NEED_BINS * sizeof(double));
    sl_array_free(a, &w->centres, 2 * sizeof(double));
    sl_free(a, w->pin, w->pin ? np * sizeof(uint32_t) : 0);
    sl_free(a, w->pmark, w->pmark ? np * sizeof(uint32_t) : 0);
    sl_free(a, w->wb, w->wb ? no * sizeof(sl_aabb) : 0);
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
    w->live = sl_alloc(&s->a, no * sizeof(uint32_t));
    w->cand = sl_alloc(&s->a, no * sizeof(uint32_t));
    w->plist = sl_alloc(&s->a, np * sizeof(uint32_t));
    w->need = sl_alloc(&s->a, NEED_BINS * sizeof(double));
    w->view = sl_calloc(&s->a, np, sizeof(pview));
    if (s->nlow && (w->wb = sl_alloc(&s->a, no * sizeof(sl_aabb))))
        memcpy(w->wb, s->bounds, (size_t)s->nobj * sizeof(sl_aabb));
    w->bounds = w->wb ? w->wb : s->bounds;
    if (!w->horizon || !w->visible || !w->okey || !w->live || !w->cand || !w->plist ||
        !w->need || !w->view || (s->nlow && !w->wb)) {
        adj_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
    }
    *out = w;
    return SL_OK;
}

/* Angular interval [*lo, *hi] (lo in [0, 2pi), hi - lo < pi) of points seen from c, and the
 * points at its ends; false when they do not lie in an open half-plane through c (c inside their
 * hull or on it, or on one of them). The extremes are found by a pseudo-angle relative to the
 * first point's direction (monotone in the true angle over (-pi, pi]); when the points fit in a
 * half-plane the extremes are right, and when they do not, the extremes are pi or more apart, which
 * the final test rejects. Only the two extremes need an atan2. */
static bool azimuth_range(double cx, double cy, const double *p, uint32_t n, double *lo, double *hi, uint32_t *ilo,
                          uint32_t *ihi)
{
    const double rx = p[0] - cx, ry = p[1] - cy;
    if (rx == 0 && ry == 0)
        return false;
    uint32_t a = 0, b = 0;
    double pa = 0, pb = 0;
    for (uint32_t i = 1; i < n; i++) {
        double dx = p[2 * i] - cx, dy = p[2 * i + 1] - cy;
        double x = rx * dx + ry * dy, y = rx * dy - ry * dx, m = fabs(x) + fabs(y);
        if (!(m > 0))
            return false;
        double q = y / m; /* (-1, 1] on the front side; beyond +-1 behind */
        if (x < 0)
            q = (y >= 0 ? 2.0 : -2.0) - q;
        if (q < pa)
            pa = q, a = i;
        if (q > pb)
            pb = q, b = i;
    }
    double ax = p[2 * a] - cx, ay = p[2 * a + 1] - cy, bx = p[2 * b] - cx, by = p[2 * b + 1] - cy;
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

/* Distance from the origin to the segment p + t e, t in [t0, t1]. */
static double seg_dist(double px, double py, double ex, double ey, double t0, double t1)
{
    double ee = ex * ex + ey * ey;
    double t = ee > 0 ? -(px * ex + py * ey) / ee : t0;
    t = fmin(t1, fmax(t0, t));
    return len2(px + t * ex, py + t * ey);
}

/* The horizon chunks of one occluder run seen from the disk (C, eps) at eye height h: the polyline
 * v[0..nv) lies inside occluders whose roofs are all at least roof (one piece's chord, or the
 * chords of touching pieces joined along their shared stretches), v[0] at azimuth lo and v[nv-1]
 * at azimuth hi from C (lifted: hi - lo < pi), all of it within a wedge of less than pi at C.
 *
 * Why it hides: for a chunk of whole bins [a0, a1] inside [lo + asin(eps/|C v0|), hi -
 * asin(eps/|C vn|)], every sight line from an eye E of the disk to a point X of the chunk's wedge
 * stays within eps of the ray C->X, so inside the band B of points within eps of the wedge's rays.
 * The polyline starts outside B on one side and ends outside it on the other (the shrinking) and
 * keeps more than eps from C, so it cuts B in two, E on the near side; an X farther from C than
 * every polyline point in B lies on the far side, so E->X crosses the polyline at a point P of B:
 * |EP| <= max |CP| + eps (occluder above the eye) and >= min |CP| - eps (below it). B is bounded
 * here by the two half-planes within eps of the wedge's edge lines (a superset of B: the bounds
 * only loosen). The chunk's key is that largest distance: the horizon takes it only for objects
 * beyond it (with the disk's 2 eps of slack). */
static bool run_chunks(adj_worker *w, const double *v, const double *ang, uint32_t nv, double lo, double hi,
                       double roof, double h, double cx, double cy, double eps, const double *zones, uint32_t nzone)
{
    const adj_shared *s = w->sh;
    const double bw = TWO_PI / s->cfg.bins;
    double ca = len2(v[0] - cx, v[1] - cy), cb = len2(v[2 * (nv - 1)] - cx, v[2 * (nv - 1) + 1] - cy);
    if (!(ca > eps) || !(cb > eps))
        return true;
    lo += asin(eps / ca);
    hi -= asin(eps / cb);
    /* bins wholly inside [lo, hi]; b0 >= 0 and b1 < 2 nb (lo < 2 pi + pi/2, hi - lo < pi) */
    int64_t b0 = (int64_t)ceil(lo / bw - 1e-12), b1 = (int64_t)floor(hi / bw + 1e-12) - 1;
    if (!(hi > lo) || b1 < b0)
        return true;
    double dnear = INFINITY, dfar = 0;
    double *widen = w->segw; /* per segment: how far (azimuth) a band point of it strays from the bins */
    for (uint32_t i = 0; i + 1 < nv; i++) {
        double px = v[2 * i] - cx, py = v[2 * i + 1] - cy;
        double d = seg_dist(px, py, v[2 * i + 2] - v[2 * i], v[2 * i + 3] - v[2 * i + 1], 0.0, 1.0);
        if (!(d > eps))
            return true; /* the run passes within eps of C: it hides nothing from the whole disk */
        dnear = d < dnear ? d : dnear;
        if (nv > 2) /* only runs use the azimuth prefilter below */
            widen[i] = asin(eps / d) + 1e-9;
    }
    for (uint32_t i = 0; i < nv; i++)
        dfar = fmax(dfar, len2(v[2 * i] - cx, v[2 * i + 1] - cy));
    /* the chunks' bin ranges: the given zones (any subset of the bins may be left out: a lower
     * horizon only keeps more), or the whole range cut where the distance grows by split */
    int64_t range[2 * MAX_CHUNKS];
    uint32_t nr = 0;
    if (nzone) {
        for (uint32_t z = 0; z < nzone && nr < MAX_CHUNKS; z++) {
            int64_t z0 = (int64_t)floor(zones[2 * z] / bw), z1 = (int64_t)ceil(zones[2 * z + 1] / bw);
            if (z0 < b0)
                z0 = b0;
            if (z1 > b1)
                z1 = b1;
            if (z0 <= z1)
                range[2 * nr] = z0, range[2 * nr + 1] = z1, nr++;
        }
    } else {
        const int64_t nbin = b1 - b0 + 1;
        int64_t nchunk = 1;
        if (s->cfg.split > 0 && dfar > s->cfg.split * dnear)
            nchunk = (int64_t)ceil(log(dfar / dnear) / s->log_split);
        if (nchunk > MAX_CHUNKS)
            nchunk = MAX_CHUNKS;
        if (nchunk > nbin)
            nchunk = nbin;
        for (int64_t j = 0; j < nchunk; j++)
            range[2 * nr] = b0 + nbin * j / nchunk, range[2 * nr + 1] = b0 + nbin * (j + 1) / nchunk - 1, nr++;
    }
    if (nr == 0) /* every zone fell outside the run's shrunk interval */
        return true;
    const sl_allocator *a = &s->a;
    size_t first = w->chunks.count;
    chunk *ch = sl_array_push(a, &w->chunks, sizeof(chunk), NULL, nr);
    keyed *ck = sl_array_push(a, &w->ckey, sizeof(keyed), NULL, nr);
    if (!ch || !ck)
        return false;
    const uint32_t nb = s->cfg.bins;
    for (uint32_t c = 0; c < nr; c++) {
        int64_t e0 = range[2 * c], e1 = range[2 * c + 1];
        /* inner normals of the wedge's edge lines (bin edges e0 and e1 + 1, from the table):
         * n . (P - C) >= -eps is the half-plane */
        const double *q0 = s->edge_sc + 2 * (e0 % nb), *q1 = s->edge_sc + 2 * ((e1 + 1) % nb);
        const double nn[2][2] = {{-q0[0], q0[1]}, {q1[0], -q1[1]}};
        double dmax = -1, dmin = INFINITY;
        const double a0 = (double)e0 * bw, a1 = (double)(e1 + 1) * bw;
        for (uint32_t i = 0; i + 1 < nv; i++) {
            /* a point of the band lies within asin(eps / r) of the bins' azimuths, r its distance
             * from C; a segment's azimuths run between its ends' (it keeps off C): skip segments
             * that cannot reach the band (runs only: a chord spans its whole range) */
            if (nv > 2) {
                double s0 = ang[i] < ang[i + 1] ? ang[i] : ang[i + 1], s1 = ang[i] < ang[i + 1] ? ang[i + 1] : ang[i];
                if (s1 < a0 - widen[i] || s0 > a1 + widen[i])
                    continue;
            }
            double px = v[2 * i] - cx, py = v[2 * i + 1] - cy;
            double ex = v[2 * i + 2] - v[2 * i], ey = v[2 * i + 3] - v[2 * i + 1];
            double t0 = 0, t1 = 1;
            for (int k = 0; k < 2 && t0 <= t1; k++) {
                double f0 = nn[k][0] * px + nn[k][1] * py + eps, fs = nn[k][0] * ex + nn[k][1] * ey;
                /* f0 + t fs >= 0 */
                if (fs > 0)
                    t0 = fmax(t0, -f0 / fs);
                else if (fs < 0)
                    t1 = fmin(t1, -f0 / fs);
                else if (f0 < 0)
                    t1 = -1;
            }
            if (!(t0 <= t1))
                continue;
            /* widen by a hair for the rounding of the clip */
            t0 = fmax(0.0, t0 - 1e-9), t1 = fmin(1.0, t1 + 1e-9);
            dmax = fmax(dmax, fmax(len2(px + t0 * ex, py + t0 * ey), len2(px + t1 * ex, py + t1 * ey)));
            dmin = fmin(dmin, seg_dist(px, py, ex, ey, t0, t1));
        }
        ch[c].b0 = e0;
        ch[c].b1 = e1;
        if (dmax < 0) { /* cannot happen for a run that crosses the wedge; hide nothing */
            ch[c].tb = -INFINITY;
            ck[c].k = INFINITY;
        } else {
            dmin = fmax(dmin, dnear);
            double tb = roof > h ? (roof - h) / (dmax + eps) : (roof - h) / (dmin - eps);
            float tf = (float)tb;
            if ((double)tf > tb) /* round down: the horizon never claims more than the bound */
                tf = nextafterf(tf, -INFINITY);
            ch[c].tb = tf;
            ck[c].k = dmax;
        }
        ck[c].id = (uint32_t)(first + c);
    }
    return true;
}

/* horizon[b] = max(horizon[b], v) for b in [b0, b1] (a loop the compiler vectorizes). */
static inline void raise_bins(float *restrict horizon, int64_t b0, int64_t b1, float v)
{
    for (int64_t b = b0; b <= b1; b++)
        horizon[b] = horizon[b] > v ? horizon[b] : v;
}

/* Is the point p on the stretch s (within the touching tolerance)? */
static bool on_stretch(const double *p, const double *s)
{
    double ex = s[2] - s[0], ey = s[3] - s[1], px = p[0] - s[0], py = p[1] - s[1];
    return seg_dist(-px, -py, ex, ey, 0.0, 1.0) <= 2 * TOUCH_TOL;
}

/* One disk of radius eps around (cx, cy) at eye height h: mark visible every live object it sees,
 * with the pieces plist[0..npl) as occluders. Leaving pieces out only lowers the horizon, so any
 * subset of the pieces gives a superset of the disk's set (still conservative). */
static bool disk(adj_worker *w, double cx, double cy, double h, double eps, uint32_t nlive, uint32_t npl)
{
    adj_shared *s = w->sh;
    const uint32_t nb = s->cfg.bins;
    const double bw = TWO_PI / nb;
    keyed *okey = w->okey;
    for (uint32_t b = 0; b < nb; b++)
        w->horizon[b] = -INFINITY;
    /* occluder pieces: shrunk intervals, cut into chunks of whole bins, each with its own tangent
     * bound; chunks sorted by the distance beyond which they hide */
    w->chunks.count = 0;
    w->ckey.count = 0;
    if (++w->stamp == 0) { /* wrapped: forget every view */
        memset(w->view, 0, ((size_t)s->npiece + 1) * sizeof(pview));
        w->stamp = 1;
    }
    const uint32_t stamp = w->stamp;
    for (uint32_t q = 0; q < npl; q++) {
        uint32_t k = w->plist[q];
        const piece *pc = &s->pieces[k];
        const double *v = s->xy + 2 * (size_t)pc->first;
        double lo, hi;
        uint32_t ia, ib;
        if (!azimuth_range(cx, cy, v, pc->count, &lo, &hi, &ia, &ib))
            continue;
        pview *pv = &w->view[k];
        pv->stamp = stamp;
        pv->succ = UINT32_MAX;
        pv->pred = 0;
        pv->lo = lo, pv->hi = hi;
        pv->ab[0] = v[2 * ia], pv->ab[1] = v[2 * ia + 1], pv->ab[2] = v[2 * ib], pv->ab[3] = v[2 * ib + 1];
        const double ang[2] = {lo, hi};
        if (!run_chunks(w, pv->ab, ang, 2, lo, hi, pc->roof, h, cx, cy, eps, NULL, 0))
            return false;
    }
    /* runs of touching pieces: piece k continues into a piece whose silhouette starts on their
     * shared stretch where k's ends, and which reaches farther round (counter-clockwise) */
    const bool fuse = s->cfg.fuse && s->ntouch;
    for (uint32_t q = 0; q < npl && fuse; q++) {
        uint32_t k = w->plist[q], best = UINT32_MAX;
        pview *pk = &w->view[k];
        if (pk->stamp != stamp)
            continue;
        double reach = pk->hi - pk->lo;
        for (uint32_t t = s->touch_start[k]; t < s->touch_start[k + 1]; t++) {
            const touch *tc = &s->touches[t];
            const pview *pq = &w->view[tc->to];
            if (pq->stamp != stamp || !on_stretch(pk->ab + 2, tc->s) || !on_stretch(pq->ab, tc->s))
                continue;
            double d = pq->lo - pk->lo;
            d -= TWO_PI * floor(d / TWO_PI + 0.5); /* into [-pi, pi] */
            double r = d + (pq->hi - pq->lo);
            if (r > reach + 1e-12 || (r == reach && best != UINT32_MAX && tc->to < best))
                reach = r, best = tc->to;
        }
        pk->succ = best;
        if (best != UINT32_MAX)
            w->view[best].pred = 1;
    }
    for (uint32_t q = 0; q < npl && fuse; q++) {
        uint32_t k = w->plist[q];
        const pview *pk = &w->view[k];
        if (pk->stamp != stamp || pk->succ == UINT32_MAX || pk->pred)
            continue;
        /* the polyline: k's chord, then each next piece's chord, joined along the stretches */
        double roof = s->pieces[k].roof, hi = pk->hi, amin = 0, amax = pk->hi - pk->lo;
        /* the run's horizon is drawn only around its joints, where the pieces on their own leave
         * gaps; elsewhere each piece (with its own roof) already does at least as well */
        double zones[2 * MAX_CHUNKS], prev_d = 0;
        uint32_t len = 0, nzone = 0;
        for (uint32_t cur = k; cur != UINT32_MAX && len < MAX_RUN; cur = w->view[cur].succ, len++) {
            const pview *pc = &w->view[cur];
            /* the run's points stay within a wedge of less than pi at C (lifted azimuths) */
            /* the piece's silhouette vertices lie at its lo and hi */
            double d = pc->lo - pk->lo;
            d -= TWO_PI * floor(d / TWO_PI + 0.5);
            double nmin = fmin(amin, d), nmax = fmax(amax, d + (pc->hi - pc->lo));
            if (!(nmax - nmin < M_PI - 1e-6))
                break;
            amin = nmin, amax = nmax;
            memcpy(w->runv + 4 * len, pc->ab, 4 * sizeof(double));
            w->runa[2 * len] = pk->lo + d;
            w->runa[2 * len + 1] = pk->lo + d + (pc->hi - pc->lo);
            roof = fmin(roof, s->pieces[cur].roof);
            if (cur != k && nzone < MAX_CHUNKS) {
                /* the joint: from the previous piece's end (at hi, prev_d from C) to this one's
                 * start; a zone only where their shrunk intervals leave a gap (with a bin to spare) */
                double ta = pk->lo + d, da = len2(pc->ab[0] - cx, pc->ab[1] - cy);
                double sp = asin(fmin(1.0, eps / prev_d)), sa = asin(fmin(1.0, eps / da));
                if (hi - sp < ta + sa + 2 * bw) {
                    double gap = (sp > sa ? sp : sa) + 2 * bw;
                    zones[2 * nzone] = (hi < ta ? hi : ta) - gap;
                    zones[2 * nzone + 1] = (hi > ta ? hi : ta) + gap;
                    nzone++;
                }
            }
            hi = pk->lo + d + (pc->hi - pc->lo);
            prev_d = len2(pc->ab[2] - cx, pc->ab[3] - cy);
        }
        if (len >= 2 && nzone && !run_chunks(w, w->runv, w->runa, 2 * len, pk->lo, hi, roof, h, cx, cy, eps, zones, nzone))
            return false;
    }
    keyed *ckey = w->ckey.data;
    const chunk *chunks = w->chunks.data;
    const size_t np = w->ckey.count;
    sort_keyed(ckey, np);
    /* live objects sorted by their nearest distance */
    for (uint32_t i = 0; i < nlive; i++) {
        const sl_aabb *b = &w->bounds[w->live[i]];
        double dx = fmax(0.0, fmax(b->min.x - cx, cx - b->max.x)), dy = fmax(0.0, fmax(b->min.y - cy, cy - b->max.y));
        okey[i].k = len2(dx, dy);
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
        while (next < np && ckey[next].k + 2 * eps <= rmin - 1e-9) {
            const chunk *c = &chunks[ckey[next].id];
            /* b0 < nb <= b1 wraps: two contiguous stretches */
            raise_bins(w->horizon, c->b0, c->b1 < (int64_t)nb ? c->b1 : (int64_t)nb - 1, c->tb);
            if (c->b1 >= (int64_t)nb)
                raise_bins(w->horizon, c->b0 > (int64_t)nb ? c->b0 - nb : 0, c->b1 - nb, c->tb);
            next++;
        }
        const sl_aabb *b = &w->bounds[o];
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
            tobj = (top - h) / (len2(fx, fy) + eps);
        }
        /* every bin the object's interval touches must hide it */
        int64_t b0 = (int64_t)floor(lo / bw), b1 = (int64_t)floor(hi / bw);
        bool hidden = true;
        for (int64_t q = b0; q <= b1 && hidden; q++)
            hidden = (double)w->horizon[q >= (int64_t)nb ? q - nb : q] >= tobj;
        if (!hidden)
            w->visible[o] = 1;
    }
    return true;
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
static uint32_t filter_pieces(adj_worker *w, double ox, double oy, double rc, double eps, uint32_t nc,
                              const uint32_t *pin, uint32_t npin, double zfloor)
{
    adj_shared *s = w->sh;
    double *need = w->need, all = -INFINITY;
    for (uint32_t b = 0; b < NEED_BINS; b++)
        need[b] = -INFINITY;
    for (uint32_t i = 0; i < nc; i++) {
        const sl_aabb *b = &w->bounds[w->cand[i]];
        double dx = fmax(0.0, fmax(b->min.x - ox, ox - b->max.x)), dy = fmax(0.0, fmax(b->min.y - oy, oy - b->max.y));
        double d = len2(dx, dy), reach = d + rc;
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
    const uint32_t nk = pin ? npin : s->npiece;
    for (uint32_t q = 0; q < nk; q++) {
        const uint32_t k = pin ? pin[q] : q;
        const piece *pc = &s->pieces[k];
        if (!(pc->base <= zfloor)) /* an eye may pass under it (sl_cell_floor) */
            continue;
        const double *v = s->xy + 2 * (size_t)pc->first;
        double near = INFINITY;
        for (uint32_t i = 0; i < pc->count; i++)
            near = fmin(near, len2(v[2 * i] - ox, v[2 * i + 1] - oy));
        /* the pieces' nearest point may be on an edge: the vertices' minimum is within the
         * piece's own extent of it, so only a lower bound is wanted here: use the box distance */
        double px0 = INFINITY, px1 = -INFINITY, py0 = INFINITY, py1 = -INFINITY;
        for (uint32_t i = 0; i < pc->count; i++) {
            px0 = fmin(px0, v[2 * i]), px1 = fmax(px1, v[2 * i]);
            py0 = fmin(py0, v[2 * i + 1]), py1 = fmax(py1, v[2 * i + 1]);
        }
        double dx = fmax(0.0, fmax(px0 - ox, ox - px1)), dy = fmax(0.0, fmax(py0 - oy, oy - py1));
        double dbox = len2(dx, dy);
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
    double tb;
    const double zfloor = sl_cell_floor(&s->bases, vc, &tb);
    if (w->wb)
        lower_boxes(w, vc, zfloor, tb);
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
            rc = fmax(rc, len2(cen[i][0] - ox, cen[i][1] - oy));
        rc = rc * (1 + 1e-9) + 1e-9;
        uint32_t npl = filter_pieces(w, ox, oy, rc, eps, nc, NULL, 0, zfloor);
        for (uint32_t i = 0; i < nc; i++)
            w->visible[w->cand[i]] = 0;
        for (size_t i = 0; i < ncen; i++) {
            uint32_t nlive = 0;
            for (uint32_t q = 0; q < nc; q++)
                if (!w->visible[w->cand[q]])
                    w->live[nlive++] = w->cand[q];
            if (nlive == 0)
                break;
            if (!disk(w, cen[i][0], cen[i][1], vc->z_max, eps, nlive, npl))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "adjustable: out of memory");
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


/* ---- the probe (pvs_update.c): may a few boxes be seen from a cell past some occluders? ----
 *
 * adj_cell's levels of disks (the same disks, radii, eye height and options), with the pieces of
 * the chosen footprints only and the given boxes as the only objects, each level testing the boxes
 * the coarser one could not hide. A box hidden at a level is hidden from every point of the cell
 * by those occluders (the level's disks cover the cell and each disk's set is conservative for it). Leaving pieces out only lowers the horizon, so
 * the pieces are gathered from a bucket grid over the rectangle that holds the disks and every box:
 * a piece that can stand between a disk and a box lies in their convex hull, inside it. */

#define PROBE_BUCKET 32.0

/* Bucket b of the probe's grid holding the piece box's corner range: [i0, i1] x [j0, j1]. */
static void probe_range(const adj_shared *s, double x0, double y0, double x1, double y1, uint32_t r[4])
{
    double f[4] = {floor((x0 - s->gx0) / s->gcell), floor((y0 - s->gy0) / s->gcell), floor((x1 - s->gx0) / s->gcell),
                   floor((y1 - s->gy0) / s->gcell)};
    double lim[4] = {s->gnx - 1.0, s->gny - 1.0, s->gnx - 1.0, s->gny - 1.0};
    for (int k = 0; k < 4; k++)
        r[k] = (uint32_t)fmin(lim[k], fmax(0.0, f[k]));
}

static sl_status probe_grid(adj_shared *s, sl_error *err)
{
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (size_t i = 0; i < s->nxy / 2; i++) {
        x0 = fmin(x0, s->xy[2 * i]), x1 = fmax(x1, s->xy[2 * i]);
        y0 = fmin(y0, s->xy[2 * i + 1]), y1 = fmax(y1, s->xy[2 * i + 1]);
    }
    if (s->npiece == 0)
        x0 = y0 = 0, x1 = y1 = 1;
    s->gx0 = x0, s->gy0 = y0;
    s->gnx = (uint32_t)fmin(4096.0, floor((x1 - x0) / PROBE_BUCKET) + 1);
    s->gny = (uint32_t)fmin(4096.0, floor((y1 - y0) / PROBE_BUCKET) + 1);
    s->gcell = fmax(PROBE_BUCKET, fmax((x1 - x0) / s->gnx, (y1 - y0) / s->gny) * (1 + 1e-9));
    const size_t nb = (size_t)s->gnx * s->gny;
    s->gstart = sl_calloc(&s->a, nb + 1, sizeof(uint32_t));
    uint32_t *fill = sl_calloc(&s->a, nb + 1, sizeof(uint32_t));
    sl_status st = SL_OK;
    if (!s->gstart || !fill)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    for (int pass = 0; pass < 2 && st == SL_OK; pass++) {
        for (uint32_t k = 0; k < s->npiece; k++) {
            const piece *pc = &s->pieces[k];
            const double *v = s->xy + 2 * (size_t)pc->first;
            double px0 = INFINITY, px1 = -INFINITY, py0 = INFINITY, py1 = -INFINITY;
            for (uint32_t i = 0; i < pc->count; i++) {
                px0 = fmin(px0, v[2 * i]), px1 = fmax(px1, v[2 * i]);
                py0 = fmin(py0, v[2 * i + 1]), py1 = fmax(py1, v[2 * i + 1]);
            }
            uint32_t r[4];
            probe_range(s, px0, py0, px1, py1, r);
            for (uint32_t j = r[1]; j <= r[3]; j++)
                for (uint32_t i = r[0]; i <= r[2]; i++) {
                    size_t b = (size_t)j * s->gnx + i;
                    if (pass == 0)
                        s->gstart[b + 1]++;
                    else
                        s->gitems[fill[b]++] = k;
                }
        }
        if (pass == 0) {
            for (size_t b = 0; b < nb; b++)
                s->gstart[b + 1] += s->gstart[b];
            s->gcount = s->gstart[nb];
            s->gitems = sl_alloc(&s->a, (s->gcount + 1) * sizeof(uint32_t));
            if (!s->gitems)
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
            for (size_t b = 0; b < nb; b++)
                fill[b] = s->gstart[b];
        }
    }
    if (fill)
        sl_free(&s->a, fill, (nb + 1) * sizeof(uint32_t));
    return st;
}

sl_status sl_adj_probe_create(sl_scene scene, sl_viewcells cells, const char *options, const uint8_t *use_footprint,
                              const sl_aabb *boxes, uint32_t nbox, const sl_allocator *alloc, void **out,
                              sl_error *err)
{
    *out = NULL;
    void *config = NULL;
    sl_status st = sl_pvs_method_configure(&sl_pvs_method_adjustable, options, alloc, &config, NULL, err);
    if (st != SL_OK)
        return st;
    void *sh = NULL;
    uint64_t removed = 0;
    st = adj_prepare_some(scene, cells, config, alloc, use_footprint, &sh, &removed, err);
    sl_free(alloc, config, sizeof(adj_config));
    if (st != SL_OK)
        return st;
    adj_shared *s = sh;
    s->probe_boxes = sl_alloc(alloc, ((size_t)nbox + 1) * sizeof(sl_aabb));
    if (!s->probe_boxes) {
        adj_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    if (nbox)
        memcpy(s->probe_boxes, boxes, (size_t)nbox * sizeof(sl_aabb));
    sl_free(alloc, s->low, s->low ? ((size_t)s->nobj + 1) * sizeof(uint32_t) : 0);
    s->low = NULL;
    s->bounds = s->probe_boxes;
    s->nobj = nbox;
    if (!find_low(s)) {
        adj_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    if ((st = probe_grid(s, err)) != SL_OK) {
        adj_release(s);
        return st;
    }
    *out = s;
    return SL_OK;
}

void sl_adj_probe_destroy(void *probe) { adj_release(probe); }

sl_status sl_adj_probe_worker_create(void *probe, void **out, sl_error *err)
{
    *out = NULL;
    adj_shared *s = probe;
    void *wv = NULL;
    sl_status st = adj_worker_create(s, &wv, err);
    if (st != SL_OK)
        return st;
    adj_worker *w = wv;
    size_t np = (size_t)s->npiece + 1;
    w->pin = sl_alloc(&s->a, np * sizeof(uint32_t));
    w->pmark = sl_calloc(&s->a, np, sizeof(uint32_t));
    if (!w->pin || !w->pmark) {
        adj_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    *out = w;
    return SL_OK;
}

void sl_adj_probe_worker_destroy(void *worker) { adj_worker_destroy(worker); }

/* adj_cell's levels over the boxes subset[0..n) (all boxes when subset is NULL); *left receives
 * how many no level could hide, their indices in w->cand[0..*left). */
static sl_status probe_run(adj_worker *w, uint32_t cell, const uint32_t *subset, uint32_t nbox, uint32_t *left,
                           sl_error *err)
{
    adj_shared *s = w->sh;
    *left = 0;
    if (nbox == 0)
        return SL_OK;
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
    int top = 0; /* adj_cell's coarsest level */
    const double extent = fmax((double)bb->max.x - bb->min.x, (double)bb->max.y - bb->min.y);
    while (top < (int)s->cfg.levels && s->cfg.eps * ldexp(1.0, top) * M_SQRT2 < extent)
        top++;
    /* adj_cell's levels, coarse to fine, the boxes a level cannot hide going on to the next: a box
     * hidden at one level (by all its disks, which cover the cell) is hidden from the whole cell */
    /* boxes reaching below a used piece's base are tested through their stand-ins (sl_cell_floor) */
    double tb;
    const double zfloor = sl_cell_floor(&s->bases, vc, &tb);
    if (w->wb)
        lower_boxes(w, vc, zfloor, tb);
    uint32_t nc = nbox;
    for (uint32_t o = 0; o < nbox; o++)
        w->cand[o] = subset ? subset[o] : o;
    for (int level = top; level >= 0 && nc > 0; level--) {
        const double eps = s->cfg.eps * ldexp(1.0, level);
        if (!level_centres(w, poly, n, bb, eps))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        const double(*cen)[2] = w->centres.data;
        const size_t ncen = w->centres.count;
        double ox = 0, oy = 0, rc = 0;
        for (size_t i = 0; i < ncen; i++)
            ox += cen[i][0], oy += cen[i][1];
        ox /= (double)ncen, oy /= (double)ncen;
        for (size_t i = 0; i < ncen; i++)
            rc = fmax(rc, len2(cen[i][0] - ox, cen[i][1] - oy));
        rc = rc * (1 + 1e-9) + 1e-9;
        /* the rectangle of the disks and the boxes, and the pieces of its buckets */
        double x0 = ox - rc - eps, x1 = ox + rc + eps, y0 = oy - rc - eps, y1 = oy + rc + eps;
        for (uint32_t q = 0; q < nc; q++) {
            const sl_aabb *bx = &w->bounds[w->cand[q]];
            x0 = fmin(x0, bx->min.x), x1 = fmax(x1, bx->max.x);
            y0 = fmin(y0, bx->min.y), y1 = fmax(y1, bx->max.y);
        }
        if (++w->pstamp == 0) {
            memset(w->pmark, 0, ((size_t)s->npiece + 1) * sizeof(uint32_t));
            w->pstamp = 1;
        }
        uint32_t npin = 0, r[4];
        probe_range(s, x0, y0, x1, y1, r); /* clamped: the border buckets hold everything beyond */
        for (uint32_t j = r[1]; j <= r[3]; j++)
            for (uint32_t i = r[0]; i <= r[2]; i++) {
                size_t b = (size_t)j * s->gnx + i;
                for (uint32_t t = s->gstart[b]; t < s->gstart[b + 1]; t++) {
                    uint32_t k = s->gitems[t];
                    if (w->pmark[k] != w->pstamp) {
                        w->pmark[k] = w->pstamp;
                        w->pin[npin++] = k;
                    }
                }
            }
        uint32_t npl = filter_pieces(w, ox, oy, rc, eps, nc, w->pin, npin, zfloor);
        for (uint32_t q = 0; q < nc; q++)
            w->visible[w->cand[q]] = 0;
        for (size_t i = 0; i < ncen; i++) {
            uint32_t nlive = 0;
            for (uint32_t q = 0; q < nc; q++)
                if (!w->visible[w->cand[q]])
                    w->live[nlive++] = w->cand[q];
            if (nlive == 0)
                break;
            if (!disk(w, cen[i][0], cen[i][1], vc->z_max, eps, nlive, npl))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        }
        uint32_t m = 0;
        for (uint32_t q = 0; q < nc; q++)
            if (w->visible[w->cand[q]])
                w->cand[m++] = w->cand[q];
        nc = m;
    }
    *left = nc;
    return SL_OK;
}

sl_status sl_adj_probe_cell(void *worker, uint32_t cell, bool *visible, sl_error *err)
{
    adj_worker *w = worker;
    uint32_t left;
    sl_status st = probe_run(w, cell, NULL, w->sh->nobj, &left, err);
    *visible = st == SL_OK && left > 0;
    return st;
}

sl_status sl_adj_probe_boxes(void *worker, uint32_t cell, const uint32_t *subset, uint32_t n, uint8_t *visible,
                             sl_error *err)
{
    adj_worker *w = worker;
    for (uint32_t i = 0; i < n; i++)
        if (subset[i] >= w->sh->nobj)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "probe: box %u of %u", subset[i], w->sh->nobj);
    uint32_t left;
    sl_status st = probe_run(w, cell, subset, n, &left, err);
    if (st != SL_OK)
        return st;
    for (uint32_t i = 0; i < left; i++)
        visible[w->cand[i]] = 1;
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

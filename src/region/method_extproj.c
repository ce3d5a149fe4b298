/* extproj: from-region visibility by extended projections.
 *
 * F. Durand, G. Drettakis, J. Thollot, C. Puech, "Conservative visibility preprocessing using
 * extended projections", SIGGRAPH 2000 (digest: ../shared/seeds/notes/002_course.md §2.16). Occluders
 * and occludees are projected onto projection planes "from the whole view cell": the extended
 * projection of an occluder is the intersection of its projections from every point of the cell,
 * that of an occludee the union. An occludee is hidden when its extended projection lies inside
 * the occluders' extended projections, fused on the plane's pixel grid (the Extended Depth Map),
 * and it lies behind them.
 *
 * Here, per view cell (PRISM or BOX: a convex polytope with 6 or 8 vertices V_i):
 *  - directions: the four horizontal axes (+x, -x, +y, -y) and, with dirs=8, the four diagonals;
 *    for one, delta(P) is the coordinate of P along its unit normal n and u the one across it, and
 *    the cell ends at delta_c = max_i delta(V_i). Vertical planes delta = d_k, with
 *    d_k = delta_c + near * growth^k (several planes per direction, the nearest just behind the
 *    street's facades), up to the scene's end;
 *  - occluders: the building footprints (convex ones as they are, the others as the triangles of
 *    their GEOS triangulation; with merge=true also the level pieces of touching footprints cut
 *    into convex pieces) as prisms [base_z, roof_z], each clipped to the slab
 *    delta_c + margin <= delta <= d_k (the paper slices occluders that cross the plane); a part of
 *    a solid occluder is a solid occluder;
 *  - the extended projection of a convex occluder O onto the plane is the intersection over the
 *    cell's vertices of the convex hulls of its vertices projected from V_i. Proof that it is
 *    exact: for a point p of the plane, the eyes E whose segment E-p meets O form a convex set
 *    (the shadow of O lit from p: for E1, E2 with o1, o2 in O on E1-p, E2-p, the segment o1-o2
 *    lies in O and crosses p-E for every E of E1-E2), so it holds the convex cell when it holds
 *    its vertices. O lies wholly between the cell and the plane (delta_c < delta < d), so every
 *    projection is a projective map of a half-space and maps the convex O to the hull of its
 *    vertices' images;
 *  - occluders are rasterized *under*: a pixel is covered only when it lies wholly inside the
 *    polygon (its four corners, with a margin against rounding); it stores the least, over the
 *    occluders covering it, of the occluder's greatest delta;
 *  - an occludee T (an object's box, delta(T) > delta_c + margin) projects, from every point of
 *    the cell, inside the bounding rectangle of its 8 corners projected from the V_i (for one eye
 *    the image of the box is the hull of its corners' images; for one corner, the image of the
 *    convex cell is the hull of the V_i's images, since the map from eye to image is projective
 *    on the half-space delta < delta(corner)); it is rasterized *over*: every pixel the rectangle
 *    touches;
 *  - T is hidden when every such pixel is covered with a depth below min delta(T). For an eye E
 *    and a point t of T, the ray E->t meets the plane at p (delta grows along it), p lies in a
 *    pixel covered by some O, so the segment E-p meets O at o with delta(o) <= max delta(O) <
 *    delta(t): o lies between E and t, inside a solid occluder.
 * The depth test is the paper's conservative one (occluder's far depth against the occludee's
 * near depth), per pixel. The tests read a max pyramid of the depth map (a coarser cell holds the
 * greatest depth of its pixels), descending into the cells that fail: the answer of reading every
 * pixel, faster.
 *
 * Not done (docs/pvs.md, "extproj"): the occlusion sweep and the reprojection of an aggregated
 * occlusion onto another plane, planes placed per occluder (here fixed distances per direction), the
 * ground and terrain as occluders, occluders other than footprints (BSP brushes, meshes).
 * Scope: PRISM and BOX cells of scenes with building footprints. */
#include "pvs_internal.h"

#include "geos_util.h"
#include "sightline/region.h"
#include "scene/scene_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

typedef struct xp_config {
    float near;      /* the first plane lies this far beyond the cell (metres) */
    float growth;    /* ratio of successive plane distances */
    uint32_t planes; /* at most this many planes per direction */
    uint32_t res;    /* pixels along the longer side of a plane's window */
    float spread;    /* a plane's window reaches spread * distance sideways and up/down */
    bool merge;      /* also the level pieces of touching footprints, as convex occluders */
    uint32_t dirs;   /* directions of the planes: 4 (the axes) or 8 (and the diagonals) */
} xp_config;

#define MAX_DIRS 8

typedef struct xp_piece {
    uint32_t first, count; /* vertices in xy, counter-clockwise, convex */
    double base, roof;
    double lo[2], hi[2]; /* box in xy */
} xp_piece;

typedef struct xp_shared {
    sl_allocator a;
    sl_scene scene;
    sl_viewcells cells;
    xp_config cfg;
    uint32_t npiece;
    xp_piece *pieces;
    double *xy;
    size_t nxy;
    uint32_t maxv; /* most vertices of a piece */
    uint32_t nobj;
    const sl_aabb *bounds;
    double scene_lo[2], scene_hi[2]; /* xy box of pieces and objects */
    double zlo, zhi;                  /* the objects' lowest and highest z */
    double dir[MAX_DIRS][2];          /* the planes' normals (unit, horizontal) */
    double *prange;                   /* per direction and piece: least and greatest delta */
    double dir_end[MAX_DIRS];         /* per direction: the greatest delta of the scene */
} xp_shared;

/* A piece's extended projection onto the current plane. */
typedef struct xp_poly {
    uint32_t first, count; /* points in the worker's poly buffer */
    float depth;           /* the clipped piece's greatest delta */
    double lo[2], hi[2];
} xp_poly;

typedef struct keyed {
    double k;
    uint32_t id;
} keyed;

typedef struct xp_worker {
    xp_shared *sh;
    float *pyr;        /* depth map and its max pyramid, level after level */
    size_t pyr_cap;    /* floats */
    uint8_t *hidden;   /* per object */
    keyed *order;      /* per piece: candidates of a direction, by near delta */
    sl_array polys;    /* xp_poly */
    sl_array pts;      /* double pairs: the polygons */
    double *cl, *fp3;  /* scratch: clipped footprint (2 per vertex), projected points */
    double *hull, *ra, *rb, *fp;
    size_t scratch;    /* points each scratch buffer holds */
} xp_worker;

static const char g_help[] =
    "near=FLOAT (default 2): distance (metres) of the first projection plane beyond the cell, per direction\n"
    "growth=FLOAT (default 2): each further plane lies this many times as far from the cell\n"
    "planes=1..32 (default 12): at most this many planes per direction (they stop past the scene)\n"
    "res=16..4096 (default 768): pixels along the longer side of a plane's window (square pixels)\n"
    "spread=0.5..8 (default 1.5): a plane's window reaches spread times its distance beyond the cell's sides\n"
    "dirs=4|8 (default 8): plane directions, the four horizontal axes or also the four diagonals\n"
    "merge=BOOL (default false): footprints that touch also form level pieces (for every roof height h, the "
    "union of the members at least h high), split into convex occluders, so that a row of buildings sharing "
    "walls occludes as one block\n";

static sl_status xp_configure(sl_opts *o, void *config, sl_error *err)
{
    xp_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "near", 2.0f, 0.05f, 10000.0f, &c->near, err)) != SL_OK ||
        (st = sl_opts_float(o, "growth", 2.0f, 1.05f, 100.0f, &c->growth, err)) != SL_OK ||
        (st = sl_opts_u32(o, "planes", 12, 1, 32, &c->planes, err)) != SL_OK ||
        (st = sl_opts_u32(o, "res", 768, 16, 4096, &c->res, err)) != SL_OK ||
        (st = sl_opts_float(o, "spread", 1.5f, 0.5f, 8.0f, &c->spread, err)) != SL_OK ||
        (st = sl_opts_bool(o, "merge", false, &c->merge, err)) != SL_OK ||
        (st = sl_opts_u32(o, "dirs", 8, 4, 8, &c->dirs, err)) != SL_OK)
        return st;
    if (c->dirs != 4 && c->dirs != 8)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "extproj: dirs must be 4 or 8 (got %u)", c->dirs);
    return SL_OK;
}

static void xp_release(void *p)
{
    xp_shared *s = p;
    if (!s)
        return;
    sl_free(&s->a, s->pieces, ((size_t)s->npiece + 1) * sizeof(xp_piece));
    sl_free(&s->a, s->xy, (s->nxy + 1) * sizeof(double));
    sl_free(&s->a, s->prange, s->prange ? 2 * (size_t)MAX_DIRS * ((size_t)s->npiece + 1) * sizeof(double) : 0);
    sl_free(&s->a, s, sizeof *s);
}

/* ---- occluder pieces ---- */

static inline double orient(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

static bool is_convex(const double *p, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++)
        if (orient(p + 2 * i, p + 2 * ((i + 1) % n), p + 2 * ((i + 2) % n)) < 0)
            return false;
    return true;
}

typedef struct xp_build {
    xp_shared *s;
    sl_array *pieces, *xy;
    double base, roof;
    double *buf;
    size_t cap;
    sl_geos *g;
    bool oom;
} xp_build;

static bool add_piece(xp_build *b, const double *v, uint32_t n)
{
    xp_piece pc = {(uint32_t)(b->xy->count / 2), n, b->base, b->roof, {DBL_MAX, DBL_MAX}, {-DBL_MAX, -DBL_MAX}};
    for (uint32_t i = 0; i < n; i++)
        for (int k = 0; k < 2; k++) {
            pc.lo[k] = fmin(pc.lo[k], v[2 * i + k]);
            pc.hi[k] = fmax(pc.hi[k], v[2 * i + k]);
        }
    if (!sl_array_push(&b->s->a, b->xy, sizeof(double), v, 2 * (size_t)n) ||
        !sl_array_push(&b->s->a, b->pieces, sizeof pc, &pc, 1)) {
        b->oom = true;
        return false;
    }
    if (n > b->s->maxv)
        b->s->maxv = n;
    return true;
}

/* One triangle of a non-convex footprint's triangulation, counter-clockwise. */
static bool add_triangle(void *user, const GEOSGeometry *poly)
{
    xp_build *b = user;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(b->g->h, poly);
    int n = ring ? sl_geos_ring_coords(b->g, ring, &b->s->a, &b->buf, &b->cap) : -1;
    if (n < 0) {
        b->oom = true;
        return false;
    }
    if (n != 3)
        return true;
    double t[6];
    memcpy(t, b->buf, sizeof t);
    double o = orient(t, t + 2, t + 4);
    if (o == 0)
        return true;
    if (o < 0) {
        double x = t[2], y = t[3];
        t[2] = t[4], t[3] = t[5], t[4] = x, t[5] = y;
    }
    return add_piece(b, t, 3);
}

/* Triangles (counter-clockwise) of a polygon, collected for merging. */
typedef struct tri_list {
    sl_geos *g;
    const sl_allocator *a;
    sl_array tris; /* double[6] */
    double *buf;
    size_t cap;
    bool oom;
} tri_list;

static bool collect_triangle(void *user, const GEOSGeometry *poly)
{
    tri_list *t = user;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(t->g->h, poly);
    int n = ring ? sl_geos_ring_coords(t->g, ring, t->a, &t->buf, &t->cap) : -1;
    if (n < 0) {
        t->oom = true;
        return false;
    }
    if (n != 3)
        return true;
    double v[6];
    memcpy(v, t->buf, sizeof v);
    double o = orient(v, v + 2, v + 4);
    if (o == 0)
        return true;
    if (o < 0) {
        double x = v[2], y = v[3];
        v[2] = v[4], v[3] = v[5], v[4] = x, v[5] = y;
    }
    if (!sl_array_push(t->a, &t->tris, sizeof v, v, 1))
        t->oom = true;
    return !t->oom;
}

#define MERGE_MAXV 32 /* vertices of a merged convex piece */

/* Union of convex CCW polygons p and q when they share an edge (exactly: both come from one
 * triangulation) and the union is convex; collinear vertices are dropped. */
static bool merge_convex(const double *p, uint32_t np, const double *q, uint32_t nq, double *out, uint32_t *nout)
{
    for (uint32_t i = 0; i < np; i++) {
        const double *a = p + 2 * i, *b = p + 2 * ((i + 1) % np);
        for (uint32_t j = 0; j < nq; j++) {
            const double *c = q + 2 * j, *d = q + 2 * ((j + 1) % nq);
            if (!(a[0] == d[0] && a[1] == d[1] && b[0] == c[0] && b[1] == c[1]))
                continue;
            double tmp[4 * MERGE_MAXV];
            uint32_t n = 0;
            for (uint32_t k = 0; k < np; k++) {
                const double *v = p + 2 * ((i + 1 + k) % np);
                tmp[2 * n] = v[0], tmp[2 * n + 1] = v[1], n++;
            }
            for (uint32_t k = 2; k < nq; k++) {
                const double *v = q + 2 * ((j + k) % nq);
                tmp[2 * n] = v[0], tmp[2 * n + 1] = v[1], n++;
            }
            /* convex with collinear vertices dropped */
            uint32_t m = 0;
            for (uint32_t k = 0; k < n; k++) {
                const double *u = tmp + 2 * ((k + n - 1) % n), *v = tmp + 2 * k, *x = tmp + 2 * ((k + 1) % n);
                double o = orient(u, v, x);
                if (o < 0)
                    return false;
                if (o > 0) {
                    if (m >= MERGE_MAXV)
                        return false;
                    out[2 * m] = v[0], out[2 * m + 1] = v[1], m++;
                }
            }
            *nout = m;
            return m >= 3;
        }
    }
    return false;
}

/* A polygon with holes (rings as sl_shrunk gives them) as GEOS geometry; NULL on failure. */
static GEOSGeometry *polygon_with_holes(sl_geos *g, const float *xy, uint32_t nrings, const uint32_t *rings)
{
    GEOSGeometry *lr[64];
    if (nrings == 0 || nrings > 64)
        return NULL;
    uint32_t first = 0, made = 0;
    for (uint32_t r = 0; r < nrings; r++) {
        uint32_t n = rings[r];
        GEOSCoordSequence *cs = n >= 3 ? GEOSCoordSeq_create_r(g->h, n + 1, 2) : NULL;
        bool ok = cs != NULL;
        for (uint32_t i = 0; ok && i <= n; i++) {
            uint32_t k = first + i % n;
            ok = GEOSCoordSeq_setXY_r(g->h, cs, i, xy[2 * k], xy[2 * k + 1]) != 0;
        }
        if (!ok && cs)
            GEOSCoordSeq_destroy_r(g->h, cs);
        lr[r] = ok ? GEOSGeom_createLinearRing_r(g->h, cs) : NULL;
        if (!lr[r])
            break;
        made++;
        first += n;
    }
    if (made < nrings) {
        for (uint32_t r = 0; r < made; r++)
            GEOSGeom_destroy_r(g->h, lr[r]);
        return NULL;
    }
    GEOSGeometry *poly = GEOSGeom_createPolygon_r(g->h, lr[0], nrings > 1 ? lr + 1 : NULL, nrings - 1);
    if (!poly)
        for (uint32_t r = 0; r < nrings; r++)
            GEOSGeom_destroy_r(g->h, lr[r]);
    return poly;
}

/* Convex pieces of a polygon (GEOS triangulation, triangles merged greedily while the union stays
 * convex) appended as occluders from base to roof. */
static sl_status add_convex_pieces(xp_shared *s, sl_geos *g, GEOSGeometry *poly, double base, double roof,
                                   sl_array *pieces, sl_array *xy, sl_error *err)
{
    GEOSGeometry *tris = GEOSConstrainedDelaunayTriangulation_r(g->h, poly);
    if (!tris)
        return sl_fail(err, SL_ERROR_INTERNAL, "extproj: GEOS could not triangulate an occluder: %s", g->message);
    tri_list tl = {.g = g, .a = &s->a};
    sl_geos_each_polygon(g, tris, collect_triangle, &tl);
    GEOSGeom_destroy_r(g->h, tris);
    sl_free(&s->a, tl.buf, tl.cap * sizeof(double));
    uint32_t nt = (uint32_t)tl.tris.count;
    double *slot = tl.oom ? NULL : sl_alloc(&s->a, ((size_t)nt + 1) * 2 * MERGE_MAXV * sizeof(double));
    uint32_t *cnt = tl.oom ? NULL : sl_calloc(&s->a, (size_t)nt + 1, sizeof(uint32_t));
    xp_build b = {.s = s, .pieces = pieces, .xy = xy, .base = base, .roof = roof, .g = g};
    if (slot && cnt) {
        for (uint32_t t = 0; t < nt; t++) {
            memcpy(slot + (size_t)t * 2 * MERGE_MAXV, (double *)tl.tris.data + 6 * (size_t)t, 6 * sizeof(double));
            cnt[t] = 3;
        }
        double tmp[2 * MERGE_MAXV];
        for (bool merged = true; merged;) {
            merged = false;
            for (uint32_t i = 0; i < nt; i++)
                for (uint32_t j = i + 1; cnt[i] && j < nt; j++) {
                    uint32_t n;
                    if (cnt[j] && merge_convex(slot + (size_t)i * 2 * MERGE_MAXV, cnt[i],
                                               slot + (size_t)j * 2 * MERGE_MAXV, cnt[j], tmp, &n)) {
                        memcpy(slot + (size_t)i * 2 * MERGE_MAXV, tmp, 2 * (size_t)n * sizeof(double));
                        cnt[i] = n, cnt[j] = 0, merged = true;
                    }
                }
        }
        for (uint32_t t = 0; t < nt && !b.oom; t++)
            if (cnt[t])
                add_piece(&b, slot + (size_t)t * 2 * MERGE_MAXV, cnt[t]);
    }
    bool oom = tl.oom || !slot || !cnt || b.oom;
    sl_free(&s->a, slot, slot ? ((size_t)nt + 1) * 2 * MERGE_MAXV * sizeof(double) : 0);
    sl_free(&s->a, cnt, cnt ? ((size_t)nt + 1) * sizeof(uint32_t) : 0);
    sl_array_free(&s->a, &tl.tris, 6 * sizeof(double));
    return oom ? sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory") : SL_OK;
}

/* The level pieces of groups of touching footprints (sl_shrink_footprints with eps 0 and merge:
 * for every roof height h of a group, the union of its members at least h high, from the highest
 * of their bases to h), as convex occluders. A lone footprint is already an occluder of its own. */
static sl_status add_merged(xp_shared *s, sl_geos *g, sl_array *pieces, sl_array *xy, sl_error *err)
{
    sl_shrunk sh;
    sl_status st = sl_shrink_footprints(s->scene, 0.0f, SL_SHRINK_CYLINDER, true, &s->a, &sh, err);
    if (st != SL_OK)
        return st;
    for (uint32_t i = 0; i < sl_shrunk_count(sh) && st == SL_OK; i++) {
        sl_shrunk_polygon sp = sl_shrunk_get(sh, i);
        if (sp.object != SL_NONE)
            continue;
        GEOSGeometry *poly = polygon_with_holes(g, sp.xy, sp.ring_count, sp.rings);
        if (!poly) {
            st = sl_fail(err, SL_ERROR_INTERNAL, "extproj: GEOS could not build merged occluder %u: %s", i, g->message);
            break;
        }
        st = add_convex_pieces(s, g, poly, sp.base_z, sp.roof_z, pieces, xy, err);
        GEOSGeom_destroy_r(g->h, poly);
    }
    sl_shrunk_destroy(sh);
    return st;
}

static sl_status add_footprint(xp_shared *s, sl_geos *g, uint32_t f, sl_array *pieces, sl_array *xy, sl_error *err)
{
    if (sl_scene_footprint_moves(s->scene, f)) /* a moving object's footprint: never an occluder */
        return SL_OK;
    sl_footprint_view fp = sl_scene_footprint(s->scene, f);
    xp_build b = {.s = s, .pieces = pieces, .xy = xy, .base = fp.base_z, .roof = fp.roof_z, .g = g};
    double *ring = sl_alloc(&s->a, 2 * (size_t)fp.vertex_count * sizeof(double));
    if (!ring)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    for (uint32_t i = 0; i < 2 * fp.vertex_count; i++)
        ring[i] = fp.xy[i];
    bool convex = is_convex(ring, fp.vertex_count);
    if (convex)
        add_piece(&b, ring, fp.vertex_count);
    sl_free(&s->a, ring, 2 * (size_t)fp.vertex_count * sizeof(double));
    if (convex)
        return b.oom ? sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory") : SL_OK;
    GEOSGeometry *poly = sl_geos_polygon(g, fp.xy, fp.vertex_count);
    GEOSGeometry *tris = poly ? GEOSConstrainedDelaunayTriangulation_r(g->h, poly) : NULL;
    if (poly)
        GEOSGeom_destroy_r(g->h, poly);
    if (!tris)
        return sl_fail(err, SL_ERROR_INTERNAL, "extproj: GEOS could not triangulate footprint %u: %s", f, g->message);
    sl_geos_each_polygon(g, tris, add_triangle, &b);
    GEOSGeom_destroy_r(g->h, tris);
    sl_free(&s->a, b.buf, b.cap * sizeof(double));
    return b.oom ? sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory") : SL_OK;
}

static sl_status xp_prepare(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                            uint32_t threads, void **shared, uint64_t *removed, sl_error *err)
{
    (void)threads;
    *removed = 0;
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t i = 0; i < sl_viewcells_count(cells); i++)
        if (vc[i].shape != SL_CELL_PRISM && vc[i].shape != SL_CELL_BOX)
            return sl_fail(err, SL_ERROR_UNSUPPORTED,
                           "extproj: view cell %u is a BSP cluster (not convex); the method needs prism or box cells "
                           "of a scene with building footprints (for Quake III maps use --method portal)",
                           i);
    if (sl_scene_footprint_count(scene) == 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "extproj: the scene has no building footprints, the method's occluders (use --method "
                       "portal for Quake III maps, or gvs, aggressive, for other models)");
    xp_shared *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    s->a = *alloc;
    s->scene = scene;
    s->cells = cells;
    s->cfg = *(const xp_config *)config;
    s->nobj = sl_scene_object_count(scene);
    s->bounds = sl_scene_object_bounds_array(scene);
    sl_geos g;
    if (!sl_geos_init(&g)) {
        xp_release(s);
        return sl_fail(err, SL_ERROR_INTERNAL, "extproj: GEOS could not start");
    }
    sl_array pieces = {0}, xy = {0};
    sl_status st = SL_OK;
    for (uint32_t f = 0; f < sl_scene_footprint_count(scene) && st == SL_OK; f++)
        st = add_footprint(s, &g, f, &pieces, &xy, err);
    if (st == SL_OK && s->cfg.merge)
        st = add_merged(s, &g, &pieces, &xy, err);
    sl_geos_finish(&g);
    s->npiece = (uint32_t)pieces.count;
    s->nxy = xy.count;
    s->pieces = st == SL_OK ? sl_realloc(alloc, pieces.data, pieces.cap * sizeof(xp_piece),
                                         ((size_t)s->npiece + 1) * sizeof(xp_piece))
                            : NULL;
    s->xy = st == SL_OK ? sl_realloc(alloc, xy.data, xy.cap * sizeof(double), (s->nxy + 1) * sizeof(double)) : NULL;
    if (!s->pieces)
        sl_array_free(alloc, &pieces, sizeof(xp_piece));
    if (!s->xy)
        sl_array_free(alloc, &xy, sizeof(double));
    if (st == SL_OK && (!s->pieces || !s->xy))
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    if (st != SL_OK) {
        xp_release(s);
        return st;
    }
    s->scene_lo[0] = s->scene_lo[1] = DBL_MAX;
    s->scene_hi[0] = s->scene_hi[1] = -DBL_MAX;
    for (uint32_t i = 0; i < s->npiece; i++)
        for (int k = 0; k < 2; k++) {
            s->scene_lo[k] = fmin(s->scene_lo[k], s->pieces[i].lo[k]);
            s->scene_hi[k] = fmax(s->scene_hi[k], s->pieces[i].hi[k]);
        }
    s->zlo = s->nobj ? DBL_MAX : 0, s->zhi = s->nobj ? -DBL_MAX : 0;
    for (uint32_t o = 0; o < s->nobj; o++) {
        const sl_aabb *b = &s->bounds[o];
        s->zlo = fmin(s->zlo, b->min.z), s->zhi = fmax(s->zhi, b->max.z);
        s->scene_lo[0] = fmin(s->scene_lo[0], b->min.x), s->scene_hi[0] = fmax(s->scene_hi[0], b->max.x);
        s->scene_lo[1] = fmin(s->scene_lo[1], b->min.y), s->scene_hi[1] = fmax(s->scene_hi[1], b->max.y);
    }
    /* the directions; a normal on an axis is exact (the slabs then cut exactly on the plane) */
    for (uint32_t k = 0; k < s->cfg.dirs; k++) {
        static const double axis[8][2] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}, {1, 1}, {-1, 1}, {-1, -1}, {1, -1}};
        double l = sqrt(axis[k][0] * axis[k][0] + axis[k][1] * axis[k][1]);
        s->dir[k][0] = axis[k][0] / l, s->dir[k][1] = axis[k][1] / l;
    }
    s->prange = sl_alloc(alloc, 2 * (size_t)MAX_DIRS * ((size_t)s->npiece + 1) * sizeof(double));
    if (!s->prange) {
        xp_release(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    }
    for (uint32_t k = 0; k < s->cfg.dirs; k++) {
        const double nx = s->dir[k][0], ny = s->dir[k][1];
        double end = -DBL_MAX;
        for (uint32_t i = 0; i < s->npiece; i++) {
            const xp_piece *pc = &s->pieces[i];
            double lo = DBL_MAX, hi = -DBL_MAX;
            for (uint32_t v = 0; v < pc->count; v++) {
                const double *q = s->xy + 2 * ((size_t)pc->first + v);
                double dl = nx * q[0] + ny * q[1];
                lo = fmin(lo, dl), hi = fmax(hi, dl);
            }
            s->prange[2 * ((size_t)k * s->npiece + i)] = lo;
            s->prange[2 * ((size_t)k * s->npiece + i) + 1] = hi;
            end = fmax(end, hi);
        }
        for (uint32_t o = 0; o < s->nobj; o++) {
            const sl_aabb *b = &s->bounds[o];
            end = fmax(end, (nx > 0 ? nx * b->max.x : nx * b->min.x) + (ny > 0 ? ny * b->max.y : ny * b->min.y));
        }
        s->dir_end[k] = end;
    }
    *shared = s;
    return SL_OK;
}

/* ---- worker ---- */

static void xp_worker_destroy(void *p)
{
    xp_worker *w = p;
    if (!w)
        return;
    const sl_allocator *a = &w->sh->a;
    sl_free(a, w->pyr, w->pyr_cap * sizeof(float));
    sl_free(a, w->hidden, (size_t)w->sh->nobj + 1);
    sl_free(a, w->order, ((size_t)w->sh->npiece + 1) * sizeof(keyed));
    sl_array_free(a, &w->polys, sizeof(xp_poly));
    sl_array_free(a, &w->pts, 2 * sizeof(double));
    size_t b = 2 * w->scratch * sizeof(double);
    sl_free(a, w->cl, b);
    sl_free(a, w->fp3, b);
    sl_free(a, w->hull, b);
    sl_free(a, w->ra, b);
    sl_free(a, w->rb, b);
    sl_free(a, w->fp, b);
    sl_free(a, w, sizeof *w);
}

#define MAX_EYES 8

static sl_status xp_worker_create(void *shared, void **out, sl_error *err)
{
    xp_shared *s = shared;
    xp_worker *w = sl_calloc(&s->a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    w->sh = s;
    size_t r = s->cfg.res;
    w->pyr_cap = 2 * r * r + 4 * r + 64; /* every level: at most (4/3) W H plus the rounding of each */
    w->pyr = sl_alloc(&s->a, w->pyr_cap * sizeof(float));
    w->hidden = sl_alloc(&s->a, (size_t)s->nobj + 1);
    w->order = sl_alloc(&s->a, ((size_t)s->npiece + 1) * sizeof(keyed));
    /* a clipped piece has maxv + 2 vertices, a prism twice that; an intersection of convex
     * polygons has at most the sum of their vertex counts */
    w->scratch = (size_t)MAX_EYES * 2 * (s->maxv + 2) + 16;
    size_t b = 2 * w->scratch * sizeof(double);
    w->cl = sl_alloc(&s->a, b);
    w->fp3 = sl_alloc(&s->a, b);
    w->hull = sl_alloc(&s->a, b);
    w->ra = sl_alloc(&s->a, b);
    w->rb = sl_alloc(&s->a, b);
    w->fp = sl_alloc(&s->a, b);
    if (!w->pyr || !w->hidden || !w->order || !w->cl || !w->fp3 || !w->hull || !w->ra || !w->rb || !w->fp) {
        xp_worker_destroy(w);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    }
    *out = w;
    return SL_OK;
}

/* ---- geometry on a plane ---- */

/* Keep the part of convex polygon p (n vertices, 2 doubles each) where delta = nx x + ny y lies in
 * [lo, hi]; into out; returns the vertex count (0: empty). */
static uint32_t clip_slab(const double *p, uint32_t n, double nx, double ny, double lo, double hi, double *tmp,
                          double *out)
{
    /* two passes of Sutherland-Hodgman: delta >= lo, then delta <= hi */
    const double *src = p;
    double *dst = tmp;
    uint32_t m = n;
    for (int pass = 0; pass < 2; pass++) {
        uint32_t k = 0;
        for (uint32_t i = 0; i < m; i++) {
            const double *c = src + 2 * i, *d = src + 2 * ((i + 1) % m);
            double dc = nx * c[0] + ny * c[1], dd = nx * d[0] + ny * d[1];
            double fc = pass == 0 ? dc - lo : hi - dc;
            double fd = pass == 0 ? dd - lo : hi - dd;
            if (fc >= 0) {
                dst[2 * k] = c[0], dst[2 * k + 1] = c[1];
                k++;
            }
            if ((fc >= 0) != (fd >= 0)) {
                double t = fc / (fc - fd);
                dst[2 * k] = c[0] + t * (d[0] - c[0]);
                dst[2 * k + 1] = c[1] + t * (d[1] - c[1]);
                /* on an axis the cut lies exactly on the slab's plane (not an ulp off it) */
                if (ny == 0)
                    dst[2 * k] = nx * (pass == 0 ? lo : hi);
                else if (nx == 0)
                    dst[2 * k + 1] = ny * (pass == 0 ? lo : hi);
                k++;
            }
        }
        m = k;
        if (m < 3)
            return 0;
        src = dst;
        dst = out;
    }
    return m;
}

static int cmp_pt(const void *x, const void *y)
{
    const double *a = x, *b = y;
    if (a[0] != b[0])
        return a[0] < b[0] ? -1 : 1;
    if (a[1] != b[1])
        return a[1] < b[1] ? -1 : 1;
    return 0;
}

/* Convex hull (counter-clockwise, no collinear points) of n points, sorted in place; into h. */
static uint32_t hull(double *p, uint32_t n, double *h)
{
    qsort(p, n, 2 * sizeof(double), cmp_pt);
    uint32_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        while (k >= 2 && orient(h + 2 * (k - 2), h + 2 * (k - 1), p + 2 * i) <= 0)
            k--;
        h[2 * k] = p[2 * i], h[2 * k + 1] = p[2 * i + 1];
        k++;
    }
    for (uint32_t i = n - 1, t = k + 1; i-- > 0;) {
        while (k >= t && orient(h + 2 * (k - 2), h + 2 * (k - 1), p + 2 * i) <= 0)
            k--;
        h[2 * k] = p[2 * i], h[2 * k + 1] = p[2 * i + 1];
        k++;
    }
    return k > 1 ? k - 1 : k;
}

/* Clip convex polygon r (n) by convex polygon c (m, counter-clockwise): their intersection into
 * out, its vertex count returned (0: empty). */
static uint32_t clip_convex(const double *r, uint32_t n, const double *c, uint32_t m, double *tmp, double *out)
{
    const double *src = r;
    double *bufs[2] = {tmp, out};
    /* the last pass must write to out: start with the buffer that makes it so */
    int which = (m % 2 == 1) ? 1 : 0;
    uint32_t cnt = n;
    for (uint32_t e = 0; e < m; e++) {
        const double *a = c + 2 * e, *b = c + 2 * ((e + 1) % m);
        double *dst = bufs[which];
        uint32_t k = 0;
        for (uint32_t i = 0; i < cnt; i++) {
            const double *p = src + 2 * i, *q = src + 2 * ((i + 1) % cnt);
            double fp = orient(a, b, p), fq = orient(a, b, q);
            if (fp >= 0) {
                dst[2 * k] = p[0], dst[2 * k + 1] = p[1];
                k++;
            }
            if ((fp >= 0) != (fq >= 0)) {
                double t = fp / (fp - fq);
                dst[2 * k] = p[0] + t * (q[0] - p[0]);
                dst[2 * k + 1] = p[1] + t * (q[1] - p[1]);
                k++;
            }
        }
        cnt = k;
        if (cnt < 3)
            return 0;
        src = dst;
        which ^= 1;
    }
    if (src != out)
        memcpy(out, src, 2 * (size_t)cnt * sizeof(double));
    return cnt;
}

/* The plane's frame: delta = nx x + ny y along the normal, u = nx y - ny x across it. */
typedef struct frame {
    double nx, ny;
    double d;                /* the plane: delta = d */
    double eye[MAX_EYES][3]; /* delta, u, z of the cell's vertices */
    uint32_t ne;
} frame;

static inline void project(const frame *f, const double *e, double dl, double u, double z, double *out)
{
    double t = (f->d - e[0]) / (dl - e[0]);
    out[0] = e[1] + (u - e[1]) * t;
    out[1] = e[2] + (z - e[2]) * t;
}

/* Extended projection of the prism over convex polygon v (n vertices, xy) from base to roof:
 * into w->ra, vertex count returned (0: empty). */
static uint32_t extended_projection(xp_worker *w, const frame *f, const double *v, uint32_t n, double base,
                                    double roof)
{
    uint32_t cnt = 0;
    double *res = w->ra;
    for (uint32_t e = 0; e < f->ne; e++) {
        const double *eye = f->eye[e];
        for (uint32_t i = 0; i < n; i++) {
            double dl = f->nx * v[2 * i] + f->ny * v[2 * i + 1], u = f->nx * v[2 * i + 1] - f->ny * v[2 * i];
            project(f, eye, dl, u, base, w->fp3 + 4 * i);
            project(f, eye, dl, u, roof, w->fp3 + 4 * i + 2);
        }
        uint32_t h = hull(w->fp3, 2 * n, w->hull);
        if (h < 3)
            return 0;
        if (e == 0) {
            memcpy(res, w->hull, 2 * (size_t)h * sizeof(double));
            cnt = h;
        } else {
            cnt = clip_convex(res, cnt, w->hull, h, w->rb, w->cl);
            if (cnt == 0)
                return 0;
            memcpy(res, w->cl, 2 * (size_t)cnt * sizeof(double));
        }
    }
    return cnt;
}

/* The interval [*l, *r] of x where the horizontal line at y meets convex polygon p; false: none. */
static bool row_span(const double *p, uint32_t n, double y, double *l, double *r)
{
    double lo = DBL_MAX, hi = -DBL_MAX;
    for (uint32_t i = 0; i < n; i++) {
        const double *a = p + 2 * i, *b = p + 2 * ((i + 1) % n);
        if ((a[1] < y && b[1] < y) || (a[1] > y && b[1] > y))
            continue;
        if (a[1] == b[1]) {
            lo = fmin(lo, fmin(a[0], b[0]));
            hi = fmax(hi, fmax(a[0], b[0]));
            continue;
        }
        double x = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
        lo = fmin(lo, x);
        hi = fmax(hi, x);
    }
    *l = lo, *r = hi;
    return lo <= hi;
}

typedef struct grid {
    double u0, z0, px; /* origin and pixel size */
    int32_t wd, ht;
    double tol;        /* rounding margin (plane units) */
    uint32_t levels;
    size_t off[24];    /* each pyramid level's first float */
    int32_t lw[24], lh[24];
} grid;

/* Under-rasterize a convex polygon: pixels wholly inside (with the margin) take min(depth). */
static void raster_occluder(float *map, const grid *g, const double *p, uint32_t n, const double *lo,
                            const double *hi, float depth)
{
    int32_t j0 = (int32_t)ceil((lo[1] + g->tol - g->z0) / g->px);
    int32_t j1 = (int32_t)floor((hi[1] - g->tol - g->z0) / g->px) - 1;
    if (j0 < 0)
        j0 = 0;
    if (j1 > g->ht - 1)
        j1 = g->ht - 1;
    for (int32_t j = j0; j <= j1; j++) {
        double y0 = g->z0 + j * g->px, y1 = y0 + g->px, l0, r0, l1, r1;
        if (!row_span(p, n, y0, &l0, &r0) || !row_span(p, n, y1, &l1, &r1))
            continue;
        double L = fmax(l0, l1) + g->tol, R = fmin(r0, r1) - g->tol;
        int32_t i0 = (int32_t)ceil((L - g->u0) / g->px), i1 = (int32_t)floor((R - g->u0) / g->px) - 1;
        if (i0 < 0)
            i0 = 0;
        if (i1 > g->wd - 1)
            i1 = g->wd - 1;
        float *row = map + (size_t)j * (size_t)g->wd;
        for (int32_t i = i0; i <= i1; i++)
            if (depth < row[i])
                row[i] = depth;
    }
}

static void build_pyramid(float *pyr, grid *g)
{
    g->off[0] = 0;
    g->lw[0] = g->wd, g->lh[0] = g->ht;
    uint32_t l = 0;
    while ((g->lw[l] > 1 || g->lh[l] > 1) && l + 1 < 24) {
        int32_t w = g->lw[l], h = g->lh[l], nw = (w + 1) / 2, nh = (h + 1) / 2;
        g->off[l + 1] = g->off[l] + (size_t)w * (size_t)h;
        g->lw[l + 1] = nw, g->lh[l + 1] = nh;
        const float *src = pyr + g->off[l];
        float *dst = pyr + g->off[l + 1];
        for (int32_t j = 0; j < nh; j++)
            for (int32_t i = 0; i < nw; i++) {
                float m = -FLT_MAX;
                for (int32_t dj = 0; dj < 2; dj++)
                    for (int32_t di = 0; di < 2; di++) {
                        int32_t x = 2 * i + di, y = 2 * j + dj;
                        float v = (x < w && y < h) ? src[(size_t)y * (size_t)w + (size_t)x] : FLT_MAX;
                        m = v > m ? v : m;
                    }
                dst[(size_t)j * (size_t)nw + (size_t)i] = m;
            }
        l++;
    }
    g->levels = l + 1;
}

/* Whether every pixel of [i0, i1] x [j0, j1] (inside the grid) holds a depth below `near`: the
 * pyramid's cells over the rectangle, from a coarse level down; a cell below `near` settles its
 * pixels, another is opened (at level 0 it fails). Exact: the same answer as reading every pixel. */
static bool cell_hidden(const float *pyr, const grid *g, uint32_t l, int32_t ci, int32_t cj, int32_t i0, int32_t i1,
                        int32_t j0, int32_t j1, float near)
{
    if (pyr[g->off[l] + (size_t)cj * (size_t)g->lw[l] + (size_t)ci] < near)
        return true;
    if (l == 0)
        return false;
    for (int32_t dj = 0; dj < 2; dj++)
        for (int32_t di = 0; di < 2; di++) {
            int32_t x = 2 * ci + di, y = 2 * cj + dj;
            /* the child's pixels: [x << (l-1), ((x+1) << (l-1)) - 1] */
            if (x >= g->lw[l - 1] || y >= g->lh[l - 1])
                continue;
            if ((((x + 1) << (l - 1)) - 1) < i0 || (x << (l - 1)) > i1 || (((y + 1) << (l - 1)) - 1) < j0 ||
                (y << (l - 1)) > j1)
                continue;
            if (!cell_hidden(pyr, g, l - 1, x, y, i0, i1, j0, j1, near))
                return false;
        }
    return true;
}

static bool rect_hidden(const float *pyr, const grid *g, int32_t i0, int32_t i1, int32_t j0, int32_t j1, float near)
{
    uint32_t l = 0;
    while (l + 1 < g->levels && ((i1 >> l) - (i0 >> l) > 1 || (j1 >> l) - (j0 >> l) > 1))
        l++;
    for (int32_t j = j0 >> l; j <= j1 >> l; j++)
        for (int32_t i = i0 >> l; i <= i1 >> l; i++)
            if (!cell_hidden(pyr, g, l, i, j, i0, i1, j0, j1, near))
                return false;
    return true;
}

static int cmp_keyed(const void *x, const void *y)
{
    const keyed *a = x, *b = y;
    if (a->k != b->k)
        return a->k < b->k ? -1 : 1;
    return a->id < b->id ? -1 : (a->id > b->id);
}

/* One direction of one cell: planes at growing distance; objects proven hidden are marked. */
static bool direction(xp_worker *w, frame *f, uint32_t dir, double delta_c, const double *cu, const double *cz, uint32_t *live,
                      uint64_t *work)
{
    xp_shared *s = w->sh;
    const xp_config *cfg = &s->cfg;
    const double margin = 1e-3;
    const double lo = delta_c + margin;
    /* candidates: pieces reaching beyond lo, by their near delta */
    uint32_t nc = 0;
    for (uint32_t i = 0; i < s->npiece; i++) {
        const xp_piece *pc = &s->pieces[i];
        (void)pc;
        double pmin = s->prange[2 * ((size_t)dir * s->npiece + i)], pmax = s->prange[2 * ((size_t)dir * s->npiece + i) + 1];
        if (pmax > lo)
            w->order[nc++] = (keyed){fmax(pmin, lo), i};
    }
    qsort(w->order, nc, sizeof(keyed), cmp_keyed);
    const double scene_end = s->dir_end[dir];
    double dist = cfg->near;
    for (uint32_t k = 0; k < cfg->planes && *live > 0; k++, dist *= cfg->growth) {
        f->d = delta_c + dist;
        const bool last = f->d >= scene_end || k + 1 == cfg->planes;
        /* window limits */
        /* window limits: sideways spread * dist beyond the cell; vertically also where the images of
         * objects can lie when they are at most half as far as the plane (an image of an object
         * beyond the plane lies between its heights and the eye's): a smaller window only keeps
         * more objects */
        double wl[2] = {cu[0] - cfg->spread * dist, fmax(cz[0] - cfg->spread * dist, s->zlo - (cz[1] - s->zlo))};
        double wh[2] = {cu[1] + cfg->spread * dist, fmin(cz[1] + cfg->spread * dist, s->zhi + (s->zhi - cz[0]))};
        w->polys.count = 0;
        w->pts.count = 0;
        double bl[2] = {DBL_MAX, DBL_MAX}, bh[2] = {-DBL_MAX, -DBL_MAX};
        for (uint32_t q = 0; q < nc && w->order[q].k < f->d; q++) {
            const xp_piece *pc = &s->pieces[w->order[q].id];
            uint32_t m = clip_slab(s->xy + 2 * (size_t)pc->first, pc->count, f->nx, f->ny, lo, f->d, w->rb, w->fp);
            if (m == 0)
                continue;
            double far = -DBL_MAX;
            for (uint32_t i = 0; i < m; i++)
                far = fmax(far, f->nx * w->fp[2 * i] + f->ny * w->fp[2 * i + 1]);
            uint32_t n = extended_projection(w, f, w->fp, m, pc->base, pc->roof);
            (*work)++;
            if (n < 3)
                continue;
            xp_poly pl = {(uint32_t)w->pts.count, n, (float)far, {DBL_MAX, DBL_MAX}, {-DBL_MAX, -DBL_MAX}};
            /* round the depth up: the float must not be nearer than the occluder's far side */
            if ((double)pl.depth < far)
                pl.depth = nextafterf(pl.depth, FLT_MAX);
            for (uint32_t i = 0; i < n; i++)
                for (int c = 0; c < 2; c++) {
                    pl.lo[c] = fmin(pl.lo[c], w->ra[2 * i + c]);
                    pl.hi[c] = fmax(pl.hi[c], w->ra[2 * i + c]);
                }
            if (pl.hi[0] <= wl[0] || pl.lo[0] >= wh[0] || pl.hi[1] <= wl[1] || pl.lo[1] >= wh[1])
                continue;
            if (!sl_array_push(&s->a, &w->pts, 2 * sizeof(double), w->ra, n) ||
                !sl_array_push(&s->a, &w->polys, sizeof pl, &pl, 1))
                return false;
            for (int c = 0; c < 2; c++) {
                bl[c] = fmin(bl[c], fmax(pl.lo[c], wl[c]));
                bh[c] = fmax(bh[c], fmin(pl.hi[c], wh[c]));
            }
        }
        if (w->polys.count > 0) {
            grid g;
            double ext = fmax(bh[0] - bl[0], bh[1] - bl[1]);
            g.px = ext / cfg->res;
            if (!(g.px > 0))
                g.px = 1e-3;
            g.u0 = bl[0], g.z0 = bl[1];
            g.wd = (int32_t)ceil((bh[0] - bl[0]) / g.px);
            g.ht = (int32_t)ceil((bh[1] - bl[1]) / g.px);
            g.wd = g.wd < 1 ? 1 : (g.wd > (int32_t)cfg->res ? (int32_t)cfg->res : g.wd);
            g.ht = g.ht < 1 ? 1 : (g.ht > (int32_t)cfg->res ? (int32_t)cfg->res : g.ht);
            double scale = fabs(g.u0) + fabs(g.z0) + ext + fabs(f->d) + 1;
            g.tol = 1e-6 * g.px + 1e-12 * scale;
            size_t npx = (size_t)g.wd * (size_t)g.ht;
            for (size_t i = 0; i < npx; i++)
                w->pyr[i] = FLT_MAX;
            const xp_poly *pl = w->polys.data;
            const double *pts = w->pts.data;
            for (size_t i = 0; i < w->polys.count; i++)
                raster_occluder(w->pyr, &g, pts + 2 * (size_t)pl[i].first, pl[i].count, pl[i].lo, pl[i].hi,
                                pl[i].depth);
            build_pyramid(w->pyr, &g);
            /* occludees */
            for (uint32_t o = 0; o < s->nobj; o++) {
                if (w->hidden[o])
                    continue;
                const sl_aabb *b = &s->bounds[o];
                double bmin[3] = {b->min.x, b->min.y, b->min.z}, bmax[3] = {b->max.x, b->max.y, b->max.z};
                /* the box's four vertical edges in the frame */
                double cd[4], cuv[4], near = DBL_MAX, far = -DBL_MAX;
                for (int c = 0; c < 4; c++) {
                    double x = (c & 1) ? bmax[0] : bmin[0], y = (c & 2) ? bmax[1] : bmin[1];
                    cd[c] = f->nx * x + f->ny * y, cuv[c] = f->nx * y - f->ny * x;
                    near = fmin(near, cd[c]), far = fmax(far, cd[c]);
                }
                (void)far;
                if (!(near >= lo))
                    continue;
                /* the corners' images: for an eye E and a corner t, u' = E_u + (t_u - E_u) s and
                 * z' = E_z + (t_z - E_z) s with s = (d - E_delta) / (t_delta - E_delta) */
                const double tz[2] = {bmin[2], bmax[2]};
                double rl[2] = {DBL_MAX, DBL_MAX}, rh[2] = {-DBL_MAX, -DBL_MAX};
                for (uint32_t e = 0; e < f->ne; e++) {
                    const double *E = f->eye[e];
                    for (int c = 0; c < 4; c++) {
                        double sc = (f->d - E[0]) / (cd[c] - E[0]);
                        double u = E[1] + (cuv[c] - E[1]) * sc;
                        rl[0] = u < rl[0] ? u : rl[0], rh[0] = u > rh[0] ? u : rh[0];
                        for (int h = 0; h < 2; h++) {
                            double z = E[2] + (tz[h] - E[2]) * sc;
                            rl[1] = z < rl[1] ? z : rl[1], rh[1] = z > rh[1] ? z : rh[1];
                        }
                    }
                }
                double fi0 = floor((rl[0] - g.tol - g.u0) / g.px), fi1 = floor((rh[0] + g.tol - g.u0) / g.px);
                double fj0 = floor((rl[1] - g.tol - g.z0) / g.px), fj1 = floor((rh[1] + g.tol - g.z0) / g.px);
                if (!(fi0 >= 0 && fj0 >= 0 && fi1 < g.wd && fj1 < g.ht))
                    continue;
                /* the float depth of the test: the occludee's near side rounded down */
                float nf = (float)near;
                if ((double)nf > near)
                    nf = nextafterf(nf, -FLT_MAX);
                if (rect_hidden(w->pyr, &g, (int32_t)fi0, (int32_t)fi1, (int32_t)fj0, (int32_t)fj1, nf)) {
                    w->hidden[o] = 1;
                    (*live)--;
                }
            }
        }
        if (last)
            break;
    }
    return true;
}

static sl_status xp_cell(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err)
{
    xp_worker *w = worker;
    xp_shared *s = w->sh;
    const sl_viewcell *vc = &sl_viewcells_data(s->cells)[cell];
    double xy[8];
    uint32_t n;
    if (vc->shape == SL_CELL_PRISM) {
        for (int i = 0; i < 3; i++)
            xy[2 * i] = vc->tri[i].x, xy[2 * i + 1] = vc->tri[i].y;
        n = 3;
    } else {
        const sl_aabb *b = &vc->bounds;
        double q[8] = {b->min.x, b->min.y, b->max.x, b->min.y, b->max.x, b->max.y, b->min.x, b->max.y};
        memcpy(xy, q, sizeof q);
        n = 4;
    }
    memset(w->hidden, 0, s->nobj);
    uint32_t live = s->nobj;
    uint64_t work = 0;
    for (uint32_t dir = 0; dir < s->cfg.dirs && live > 0; dir++) {
        frame f = {.nx = s->dir[dir][0], .ny = s->dir[dir][1], .ne = 2 * n};
        double delta_c = -DBL_MAX, cu[2] = {DBL_MAX, -DBL_MAX}, cz[2] = {vc->z_min, vc->z_max};
        for (uint32_t i = 0; i < n; i++)
            for (int h = 0; h < 2; h++) {
                double *e = f.eye[2 * i + (uint32_t)h];
                e[0] = f.nx * xy[2 * i] + f.ny * xy[2 * i + 1];
                e[1] = f.nx * xy[2 * i + 1] - f.ny * xy[2 * i];
                e[2] = h ? vc->z_max : vc->z_min;
                delta_c = fmax(delta_c, e[0]);
                cu[0] = fmin(cu[0], e[1]), cu[1] = fmax(cu[1], e[1]);
            }
        if (!direction(w, &f, dir, delta_c, cu, cz, &live, &work))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "extproj: out of memory");
    }
    uint32_t m = 0;
    for (uint32_t o = 0; o < s->nobj; o++)
        if (!w->hidden[o])
            out->ids[m++] = o;
    out->count = m;
    out->work = work;
    return SL_OK;
}

const sl_pvs_method sl_pvs_method_extproj = {
    .name = "extproj",
    .summary = "extended projections: occluders (footprint prisms) and occludees projected from the whole cell onto "
               "planes and fused in an extended depth map (Durand et al. 2000); conservative",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(xp_config),
    .configure = xp_configure,
    .prepare = xp_prepare,
    .worker_create = xp_worker_create,
    .cell = xp_cell,
    .worker_destroy = xp_worker_destroy,
    .release = xp_release,
    .notice = NULL,
};

/* Occluder shrinking: erosion of occluders by eps so that point samples stand for whole regions.
 *
 * P. Wonka, PhD thesis, TU Wien 2001, chapter 7: Theorem 3 (an occluder eroded by eps hides from V
 * only what the original hides from every point within eps of V), section 7.3 (shrinking in 2D,
 * 2.5D and 3D) and section 7.4 / Lemma 6 (erosion by a horizontal disk — a cylinder — for viewers
 * that move on the ground, with occlusion computed from the highest eye point).
 *
 * 2D (footprints): GEOS's buffer with a negative distance is exact erosion by a disk, except that
 * the round joins — arcs around reflex corners of the footprint — are drawn as chords, which lie
 * closer to the corner than the arc. The buffer radius is therefore eps / cos(pi / (4 q)) for q
 * segments per quarter circle, so that every chord stays at least eps from the corner, plus a
 * margin for rounding the result to float. Pieces come out counter-clockwise; slivers below 1e-6
 * m^2 are dropped (dropping an occluder is always conservative).
 *
 * 2.5D (height fields): grayscale erosion, the minimum over the eps-disk. The field between samples
 * is bilinear, so a sample's new value is the minimum of the samples within eps + 2 sqrt(2) cells:
 * that bounds the continuous minimum over the disk of every point of the four squares around it,
 * hence the bilinear result is nowhere above the exact erosion.
 *
 * 3D (meshes): voxels. A voxel is solid when its eight corners are inside the closed mesh (ray
 * parity) and no triangle overlaps its box (separating axis test), so a solid voxel lies wholly
 * inside. A voxel is kept when every voxel whose box is nearer than eps to its box is solid: then
 * every point of it is at least eps from the outside. */
#include "pvs/viewcells_internal.h"

#include "core/dvec3.h"
#include "geos_util.h"
#include "scene/scene_internal.h"

#include <float.h>
#include <stdlib.h>
#include <math.h>

#define QUAD_SEGS 8
#define MIN_PIECE_AREA 1e-6

struct sl_shrunk_t {
    sl_allocator alloc;
    sl_array polys;    /* sl_shrunk_polygon (xy pointers set at the end) */
    sl_array offsets;  /* uint32 pairs: first vertex in xy, first ring in rings */
    sl_array rings;    /* uint32: vertices per ring */
    sl_array xy;       /* float */
    sl_array vanished; /* uint32 */
    sl_shrink_stats stats;
};

void sl_shrunk_destroy(sl_shrunk s)
{
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    sl_array_free(a, &s->polys, sizeof(sl_shrunk_polygon));
    sl_array_free(a, &s->offsets, 2 * sizeof(uint32_t));
    sl_array_free(a, &s->rings, sizeof(uint32_t));
    sl_array_free(a, &s->xy, sizeof(float));
    sl_array_free(a, &s->vanished, sizeof(uint32_t));
    sl_free(a, s, sizeof *s);
}

uint32_t sl_shrunk_count(sl_shrunk s) { return s ? (uint32_t)s->polys.count : 0; }

sl_shrunk_polygon sl_shrunk_get(sl_shrunk s, uint32_t i)
{
    sl_shrunk_polygon p;
    memset(&p, 0, sizeof p);
    if (!s || i >= s->polys.count)
        return p;
    p = SL_AT(s->polys, sl_shrunk_polygon, i);
    const uint32_t *off = (const uint32_t *)s->offsets.data + 2 * (size_t)i;
    p.xy = (const float *)s->xy.data + 2 * (size_t)off[0];
    p.rings = (const uint32_t *)s->rings.data + off[1];
    return p;
}

uint32_t sl_shrunk_vanished(sl_shrunk s, const uint32_t **ids)
{
    if (ids)
        *ids = s ? s->vanished.data : NULL;
    return s ? (uint32_t)s->vanished.count : 0;
}

void sl_shrunk_get_stats(sl_shrunk s, sl_shrink_stats *out)
{
    if (!out)
        return;
    if (!s)
        memset(out, 0, sizeof *out);
    else
        *out = s->stats;
}

typedef struct piece_sink {
    struct sl_shrunk_t *s;
    sl_geos *g;
    const sl_footprint_view *fp; /* unused: kept NULL */
    uint32_t footprint, object;
    float base, roof;
    uint32_t pieces;
    double *buf;
    size_t buf_cap;
    bool oom;
} piece_sink;

/* Append one ring (n vertices in k->buf, closing vertex dropped) with the wanted orientation. */
static bool put_ring(piece_sink *k, int n, bool ccw, double *area)
{
    struct sl_shrunk_t *s = k->s;
    double area2 = 0;
    for (int i = 0, j = n - 1; i < n; j = i++)
        area2 += k->buf[2 * j] * k->buf[2 * i + 1] - k->buf[2 * i] * k->buf[2 * j + 1];
    float *dst = sl_array_push(&s->alloc, &s->xy, sizeof(float), NULL, 2 * (size_t)n);
    uint32_t nv = (uint32_t)n;
    if (!dst || !sl_array_push(&s->alloc, &s->rings, sizeof nv, &nv, 1))
        return false;
    bool flip = (area2 > 0) != ccw;
    for (int i = 0; i < n; i++) {
        int src = flip ? n - 1 - i : i;
        dst[2 * i] = (float)k->buf[2 * src];
        dst[2 * i + 1] = (float)k->buf[2 * src + 1];
    }
    *area = 0.5 * fabs(area2);
    return true;
}

/* One polygon of the buffer result: its outer ring and, for a merged group around a courtyard,
 * its holes (without them the courtyard would be taken as solid). */
static bool take_piece(void *user, const GEOSGeometry *poly)
{
    piece_sink *k = user;
    struct sl_shrunk_t *s = k->s;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(k->g->h, poly);
    int n = ring ? sl_geos_ring_coords(k->g, ring, &s->alloc, &k->buf, &k->buf_cap) : -1;
    if (n < 0) {
        k->oom = true;
        return false;
    }
    if (n < 3)
        return true;
    double a0 = 0;
    for (int i = 0, j = n - 1; i < n; j = i++)
        a0 += k->buf[2 * j] * k->buf[2 * i + 1] - k->buf[2 * i] * k->buf[2 * j + 1];
    if (fabs(a0) * 0.5 < MIN_PIECE_AREA)
        return true;
    uint32_t first[2] = {(uint32_t)(s->xy.count / 2), (uint32_t)s->rings.count};
    size_t xy0 = s->xy.count, r0 = s->rings.count;
    double area;
    if (!put_ring(k, n, true, &area)) {
        k->oom = true;
        return false;
    }
    uint32_t nrings = 1, nverts = (uint32_t)n;
    int holes = GEOSGetNumInteriorRings_r(k->g->h, poly);
    for (int h = 0; h < holes; h++) {
        const GEOSGeometry *hr = GEOSGetInteriorRingN_r(k->g->h, poly, h);
        int m = hr ? sl_geos_ring_coords(k->g, hr, &s->alloc, &k->buf, &k->buf_cap) : -1;
        if (m < 0) {
            k->oom = true;
            return false;
        }
        if (m < 3)
            continue;
        /* a hole is never dropped: dropping it would fill the courtyard */
        if (!put_ring(k, m, false, &area)) {
            k->oom = true;
            return false;
        }
        nrings++;
        nverts += (uint32_t)m;
    }
    (void)xy0, (void)r0;
    sl_shrunk_polygon p;
    memset(&p, 0, sizeof p);
    p.vertex_count = nverts;
    p.ring_count = nrings;
    p.base_z = k->base;
    p.roof_z = k->roof;
    p.footprint = k->footprint;
    p.object = k->object;
    if (!sl_array_push(&s->alloc, &s->polys, sizeof p, &p, 1) ||
        !sl_array_push(&s->alloc, &s->offsets, 2 * sizeof(uint32_t), first, 1)) {
        k->oom = true;
        return false;
    }
    k->pieces++;
    return true;
}

/* Union-find over footprints. */
static uint32_t uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

typedef struct fp_info {
    double x0, y0, x1, y1;
    uint32_t id;
} fp_info;

static int cmp_fp_x0(const void *a, const void *b)
{
    const fp_info *p = a, *q = b;
    if (p->x0 != q->x0)
        return p->x0 < q->x0 ? -1 : 1;
    return (p->id > q->id) - (p->id < q->id);
}

/* Members of one group: footprint ids sorted by roof height, highest first (ties by id). */
typedef struct member {
    float roof;
    uint32_t id;
} member;

static int cmp_member(const void *a, const void *b)
{
    const member *p = a, *q = b;
    if (p->roof != q->roof)
        return p->roof > q->roof ? -1 : 1;
    return (p->id > q->id) - (p->id < q->id);
}

sl_status sl_shrink_footprints(sl_scene scene, float eps, sl_shrink_mode mode, bool merge, const sl_allocator *alloc,
                               sl_shrunk *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_shrink_footprints: scene and out must not be NULL");
    *out = NULL;
    if (!isfinite(eps) || eps < 0 || eps > 1e4f)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: eps %g is outside [0, 10000] m", (double)eps);
    if (mode != SL_SHRINK_CYLINDER && mode != SL_SHRINK_BALL)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: unknown mode %d", (int)mode);
    double t0 = sl_now();
    alloc = sl_alloc_or_default(alloc);
    struct sl_shrunk_t *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory");
    s->alloc = *alloc;
    sl_geos g;
    if (!sl_geos_init(&g)) {
        sl_shrunk_destroy(s);
        return sl_fail(err, SL_ERROR_INTERNAL, "shrink: GEOS could not start");
    }
    uint32_t nf = sl_scene_footprint_count(scene);
    s->stats.footprints = nf;
    size_t n1 = (size_t)nf + 1;
    GEOSGeometry **geo = sl_calloc(alloc, n1, sizeof *geo);
    uint32_t *parent = sl_alloc(alloc, n1 * sizeof(uint32_t));
    fp_info *info = sl_alloc(alloc, n1 * sizeof(fp_info));
    member *mem = sl_alloc(alloc, n1 * sizeof(member));
    uint8_t *alive = sl_calloc(alloc, n1, 1);
    GEOSBufferParams *bp = GEOSBufferParams_create_r(g.h);
    sl_status st = SL_OK;
    piece_sink k;
    memset(&k, 0, sizeof k);
    k.s = s;
    k.g = &g;
    if (!geo || !parent || !info || !mem || !alive) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory for %u footprints", nf);
        goto done;
    }
    if (!bp || !GEOSBufferParams_setJoinStyle_r(g.h, bp, GEOSBUF_JOIN_ROUND) ||
        !GEOSBufferParams_setQuadrantSegments_r(g.h, bp, QUAD_SEGS)) {
        st = sl_fail(err, SL_ERROR_INTERNAL, "shrink: GEOS buffer parameters: %s", g.message);
        goto done;
    }
    float big = 0;
    for (uint32_t f = 0; f < nf && st == SL_OK; f++) {
        sl_footprint_view fp = sl_scene_footprint(scene, f);
        parent[f] = f;
        info[f].id = f;
        info[f].x0 = info[f].y0 = INFINITY;
        info[f].x1 = info[f].y1 = -INFINITY;
        /* a moving object's footprint is left out: no geometry, an empty box (it meets no other
         * footprint in the sweep), no group of its own below */
        if (sl_scene_footprint_moves(scene, f))
            continue;
        for (uint32_t i = 0; i < fp.vertex_count; i++) {
            double x = fp.xy[2 * i], y = fp.xy[2 * i + 1];
            info[f].x0 = fmin(info[f].x0, x), info[f].x1 = fmax(info[f].x1, x);
            info[f].y0 = fmin(info[f].y0, y), info[f].y1 = fmax(info[f].y1, y);
            big = fmaxf(big, fmaxf(fabsf(fp.xy[2 * i]), fabsf(fp.xy[2 * i + 1])));
        }
        geo[f] = sl_geos_polygon(&g, fp.xy, fp.vertex_count);
        if (!geo[f])
            st = sl_fail(err, SL_ERROR_INTERNAL, "shrink: GEOS could not take footprint %u: %s", f, g.message);
    }
    /* groups: footprints that touch or overlap (sweep over x, exact GEOS test on box overlaps) */
    if (merge && st == SL_OK) {
        fp_info *sorted = sl_alloc(alloc, n1 * sizeof(fp_info));
        if (!sorted) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory");
            goto done;
        }
        memcpy(sorted, info, (size_t)nf * sizeof(fp_info));
        qsort(sorted, nf, sizeof *sorted, cmp_fp_x0);
        for (uint32_t i = 0; i < nf && st == SL_OK; i++)
            for (uint32_t j = i + 1; j < nf && sorted[j].x0 <= sorted[i].x1; j++) {
                const fp_info *a = &sorted[i], *b = &sorted[j];
                if (b->y0 > a->y1 || b->y1 < a->y0)
                    continue;
                uint32_t ra = uf_find(parent, a->id), rb = uf_find(parent, b->id);
                if (ra == rb)
                    continue;
                char hit = GEOSIntersects_r(g.h, geo[a->id], geo[b->id]);
                if (hit == 2) {
                    st = sl_fail(err, SL_ERROR_INTERNAL, "shrink: GEOS failed on footprints %u and %u: %s", a->id,
                                 b->id, g.message);
                    break;
                }
                if (hit)
                    parent[SL_MAX(ra, rb)] = SL_MIN(ra, rb); /* the lowest id roots the group */
            }
        sl_free(alloc, sorted, n1 * sizeof(fp_info));
    }
    /* the margin that keeps the chords of the round joins eps away, plus float rounding */
    double r = eps / cos(M_PI / (4.0 * QUAD_SEGS)) + 8.0 * FLT_EPSILON * (1.0 + big);
    /* each group, in the order of its lowest footprint: one layer per distinct roof height, the
     * union of the members at least that high, eroded (the level sets of the height-field erosion) */
    for (uint32_t root = 0; root < nf && st == SL_OK; root++) {
        if (uf_find(parent, root) != root || !geo[root])
            continue;
        uint32_t nm = 0;
        for (uint32_t f = root; f < nf; f++)
            if (uf_find(parent, f) == root)
                mem[nm++] = (member){sl_scene_footprint(scene, f).roof_z, f};
        qsort(mem, nm, sizeof *mem, cmp_member);
        GEOSGeometry *acc = NULL;
        float base_max = -INFINITY;
        for (uint32_t i = 0; i < nm && st == SL_OK;) {
            float roof = mem[i].roof;
            uint32_t e = i;
            while (e < nm && mem[e].roof == roof) {
                sl_footprint_view fp = sl_scene_footprint(scene, mem[e].id);
                base_max = fmaxf(base_max, fp.base_z);
                GEOSGeometry *u = acc ? GEOSUnion_r(g.h, acc, geo[mem[e].id]) : GEOSGeom_clone_r(g.h, geo[mem[e].id]);
                if (acc)
                    GEOSGeom_destroy_r(g.h, acc);
                acc = u;
                if (!acc) {
                    st = sl_fail(err, SL_ERROR_INTERNAL, "shrink: GEOS could not unite footprint %u: %s", mem[e].id,
                                 g.message);
                    break;
                }
                e++;
            }
            if (st != SL_OK)
                break;
            float base = base_max, top = roof;
            if (mode == SL_SHRINK_BALL)
                base += eps, top -= eps;
            size_t before = s->polys.count;
            if (top > base) {
                k.fp = NULL;
                k.footprint = mem[i].id;
                k.object = nm == 1 ? sl_scene_footprint(scene, mem[i].id).object : SL_NONE;
                k.base = base;
                k.roof = top;
                k.pieces = 0;
                GEOSGeometry *res = GEOSBufferWithParams_r(g.h, acc, bp, -r);
                if (!res) {
                    st = sl_fail(err, SL_ERROR_INTERNAL, "shrink: GEOS could not erode footprint %u's group: %s",
                                 mem[i].id, g.message);
                    break;
                }
                sl_geos_each_polygon(&g, res, take_piece, &k);
                GEOSGeom_destroy_r(g.h, res);
                if (k.oom) {
                    st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory at footprint %u", mem[i].id);
                    break;
                }
            }
            /* the members at this height survive when a piece of this layer overlaps them */
            for (size_t q = before; q < s->polys.count; q++) {
                sl_shrunk_polygon pp = sl_shrunk_get(s, (uint32_t)q);
                GEOSGeometry *pg = sl_geos_polygon(&g, pp.xy, pp.rings[0]); /* the outer ring */
                for (uint32_t m = i; pg && m < e; m++)
                    if (!alive[mem[m].id] && GEOSIntersects_r(g.h, pg, geo[mem[m].id]) == 1)
                        alive[mem[m].id] = 1;
                if (pg)
                    GEOSGeom_destroy_r(g.h, pg);
            }
            if (s->polys.count - before > 1)
                s->stats.split++;
            i = e;
        }
        if (acc)
            GEOSGeom_destroy_r(g.h, acc);
    }
    for (uint32_t f = 0; f < nf && st == SL_OK; f++) {
        if (sl_scene_footprint_moves(scene, f))
            continue; /* left out, neither kept nor vanished */
        if (alive[f]) {
            s->stats.kept++;
        } else {
            s->stats.vanished++;
            if (!sl_array_push(&s->alloc, &s->vanished, sizeof f, &f, 1))
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory");
        }
    }
done:
    sl_free(&s->alloc, k.buf, k.buf_cap * sizeof(double));
    if (geo)
        for (uint32_t f = 0; f < nf; f++)
            if (geo[f])
                GEOSGeom_destroy_r(g.h, geo[f]);
    sl_free(alloc, geo, n1 * sizeof *geo);
    sl_free(alloc, parent, n1 * sizeof(uint32_t));
    sl_free(alloc, info, n1 * sizeof(fp_info));
    sl_free(alloc, mem, n1 * sizeof(member));
    sl_free(alloc, alive, n1);
    if (bp)
        GEOSBufferParams_destroy_r(g.h, bp);
    sl_geos_finish(&g);
    if (st != SL_OK) {
        sl_shrunk_destroy(s);
        return st;
    }
    s->stats.pieces = (uint32_t)s->polys.count;
    s->stats.seconds = sl_now() - t0;
    *out = s;
    return SL_OK;
}

/* ---- 2.5D ---- */

sl_status sl_shrink_heightfield(const float *h, uint32_t nx, uint32_t ny, float cell, float eps, sl_shrink_mode mode,
                                float *out, sl_error *err)
{
    if (!h || !out || h == out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_shrink_heightfield: heights and out must be distinct arrays");
    if (nx < 2 || ny < 2 || (uint64_t)nx * ny > (1u << 30))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: height field %u x %u is outside 2..2^30 samples", nx, ny);
    if (!isfinite(cell) || !(cell > 0) || !isfinite(eps) || eps < 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: cell %g must be > 0 and eps %g >= 0", (double)cell,
                       (double)eps);
    double reach = eps + 2.0 * M_SQRT2 * cell; /* see the file comment */
    int64_t rad = (int64_t)ceil(reach / cell);
    if (rad > 4096)
        return sl_fail(err, SL_ERROR_LIMIT, "shrink: eps %g is %lld cells: too large for this field", (double)eps,
                       (long long)rad);
    for (int64_t j = 0; j < ny; j++)
        for (int64_t i = 0; i < nx; i++) {
            float m = INFINITY;
            for (int64_t dj = -rad; dj <= rad; dj++) {
                int64_t y = j + dj;
                if (y < 0 || y >= ny)
                    continue;
                for (int64_t di = -rad; di <= rad; di++) {
                    int64_t x = i + di;
                    if (x < 0 || x >= nx || (double)(di * di + dj * dj) * cell * cell > reach * reach)
                        continue;
                    m = fminf(m, h[y * nx + x]);
                }
            }
            out[j * nx + i] = mode == SL_SHRINK_BALL ? m - eps : m;
        }
    return SL_OK;
}

/* ---- 3D ---- */

/* Ray parity along a skewed direction from p: inside when odd. */
static bool point_inside(const float *pos, const uint32_t *idx, uint32_t nt, const double p[3])
{
    const double d[3] = {0.8727, 0.3141, 0.3737};
    uint32_t hits = 0;
    for (uint32_t k = 0; k < nt; k++) {
        double v[3][3];
        for (int j = 0; j < 3; j++)
            for (int i = 0; i < 3; i++)
                v[j][i] = pos[3 * (size_t)idx[3 * k + (uint32_t)j] + (size_t)i];
        hits += sl_ray_triangle(p, d, v[0], v[1], v[2], 1e-18, NULL); /* src/core/dvec3.c */
    }
    return hits & 1;
}

/* Triangle / box overlap by separating axes (box centre c, half size h); touching counts. */
static bool tri_box_overlap(const double c[3], double h, const float *ta, const float *tb, const float *tc)
{
    double v[3][3];
    for (int i = 0; i < 3; i++) {
        v[0][i] = ta[i] - c[i];
        v[1][i] = tb[i] - c[i];
        v[2][i] = tc[i] - c[i];
    }
    for (int ax = 0; ax < 3; ax++) {
        double lo = fmin(v[0][ax], fmin(v[1][ax], v[2][ax])), hi = fmax(v[0][ax], fmax(v[1][ax], v[2][ax]));
        if (lo > h || hi < -h)
            return false;
    }
    double e[3][3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            e[i][k] = v[(i + 1) % 3][k] - v[i][k];
    double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                   e[0][0] * e[1][1] - e[0][1] * e[1][0]};
    double d = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
    double r = h * (fabs(n[0]) + fabs(n[1]) + fabs(n[2]));
    if (fabs(d) > r)
        return false;
    for (int i = 0; i < 3; i++)
        for (int ax = 0; ax < 3; ax++) {
            /* axis = unit axis x edge i */
            double a[3] = {0, 0, 0};
            double u[3] = {ax == 0, ax == 1, ax == 2};
            a[0] = u[1] * e[i][2] - u[2] * e[i][1];
            a[1] = u[2] * e[i][0] - u[0] * e[i][2];
            a[2] = u[0] * e[i][1] - u[1] * e[i][0];
            double p0 = a[0] * v[0][0] + a[1] * v[0][1] + a[2] * v[0][2];
            double p1 = a[0] * v[1][0] + a[1] * v[1][1] + a[2] * v[1][2];
            double p2 = a[0] * v[2][0] + a[1] * v[2][1] + a[2] * v[2][2];
            double rr = h * (fabs(a[0]) + fabs(a[1]) + fabs(a[2]));
            if (fmin(p0, fmin(p1, p2)) > rr || fmax(p0, fmax(p1, p2)) < -rr)
                return false;
        }
    return true;
}

void sl_shrink_boxes_free(const sl_allocator *alloc, sl_aabb *boxes, uint32_t count)
{
    sl_free(sl_alloc_or_default(alloc), boxes, ((size_t)count + 1) * sizeof(sl_aabb));
}

sl_status sl_shrink_mesh_voxels(const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt, float voxel, float eps,
                                const sl_allocator *alloc, sl_aabb **boxes, uint32_t *count, sl_error *err)
{
    if (!boxes || !count || (nt && (!pos || !idx)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_shrink_mesh_voxels: arguments must not be NULL");
    *boxes = NULL;
    *count = 0;
    alloc = sl_alloc_or_default(alloc);
    if (!isfinite(voxel) || !(voxel > 0) || !isfinite(eps) || eps < 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: voxel %g must be > 0 and eps %g >= 0", (double)voxel,
                       (double)eps);
    sl_aabb b = sl_aabb_empty();
    for (uint32_t k = 0; k < 3 * nt; k++) {
        if (idx[k] >= nv)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: index %u of triangle %u is out of range", idx[k], k / 3);
        const float *p = pos + 3 * (size_t)idx[k];
        if (!sl_finite3(p))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: vertex %u is not finite", idx[k]);
        sl_aabb_grow(&b, (sl_vec3){p[0], p[1], p[2]});
    }
    if (nt == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "shrink: the mesh has no triangles");
    double n3[3];
    uint32_t n[3];
    for (int a = 0; a < 3; a++) {
        n3[a] = ceil(((double)(&b.max.x)[a] - (&b.min.x)[a]) / voxel);
        n3[a] = fmax(n3[a], 1);
    }
    if (n3[0] * n3[1] * n3[2] > 64e6)
        return sl_fail(err, SL_ERROR_LIMIT, "shrink: %.0f x %.0f x %.0f voxels of %g m is too many", n3[0], n3[1], n3[2],
                       (double)voxel);
    for (int a = 0; a < 3; a++)
        n[a] = (uint32_t)n3[a];
    size_t total = (size_t)n[0] * n[1] * n[2];
    size_t corners = (size_t)(n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    uint8_t *inside = sl_calloc(alloc, corners, 1);
    uint8_t *solid = sl_calloc(alloc, total, 1);
    uint8_t *kept = sl_calloc(alloc, total, 1);
    sl_array out = {0};
    sl_status st = SL_OK;
    if (!inside || !solid || !kept) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory for %zu voxels", total);
        goto done;
    }
#define CI(i, j, k) (((size_t)(k) * (n[1] + 1) + (j)) * (n[0] + 1) + (i))
#define VI(i, j, k) (((size_t)(k) * n[1] + (j)) * n[0] + (i))
    for (uint32_t k = 0; k <= n[2]; k++)
        for (uint32_t j = 0; j <= n[1]; j++)
            for (uint32_t i = 0; i <= n[0]; i++) {
                double p[3] = {b.min.x + (double)i * voxel, b.min.y + (double)j * voxel, b.min.z + (double)k * voxel};
                inside[CI(i, j, k)] = point_inside(pos, idx, nt, p);
            }
    for (uint32_t k = 0; k < n[2]; k++)
        for (uint32_t j = 0; j < n[1]; j++)
            for (uint32_t i = 0; i < n[0]; i++) {
                bool all = true;
                for (int c = 0; c < 8 && all; c++)
                    all = inside[CI(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))];
                solid[VI(i, j, k)] = all;
            }
    /* a triangle crossing a voxel means the outside may be in it */
    for (uint32_t t = 0; t < nt; t++) {
        const float *ta = pos + 3 * (size_t)idx[3 * t], *tb = pos + 3 * (size_t)idx[3 * t + 1],
                    *tc = pos + 3 * (size_t)idx[3 * t + 2];
        uint32_t lo[3], hi[3];
        for (int a = 0; a < 3; a++) {
            double mn = fmin(ta[a], fmin(tb[a], tc[a])), mx = fmax(ta[a], fmax(tb[a], tc[a]));
            double o = (&b.min.x)[a];
            lo[a] = (uint32_t)fmax(0, floor((mn - o) / voxel) - 1);
            hi[a] = (uint32_t)fmin(n[a] - 1, floor((mx - o) / voxel) + 1);
        }
        for (uint32_t k = lo[2]; k <= hi[2]; k++)
            for (uint32_t j = lo[1]; j <= hi[1]; j++)
                for (uint32_t i = lo[0]; i <= hi[0]; i++) {
                    if (!solid[VI(i, j, k)])
                        continue;
                    double c[3] = {b.min.x + (i + 0.5) * voxel, b.min.y + (j + 0.5) * voxel,
                                   b.min.z + (k + 0.5) * voxel};
                    if (tri_box_overlap(c, 0.5 * voxel, ta, tb, tc))
                        solid[VI(i, j, k)] = 0;
                }
    }
    /* erosion: voxels whose gap to this one is below eps must all be solid (outside the grid is
     * outside the mesh) */
    int32_t r = (int32_t)ceil(eps / voxel) + 1;
    for (uint32_t k = 0; k < n[2]; k++)
        for (uint32_t j = 0; j < n[1]; j++)
            for (uint32_t i = 0; i < n[0]; i++) {
                if (!solid[VI(i, j, k)])
                    continue;
                bool ok = true;
                for (int32_t dk = -r; dk <= r && ok; dk++)
                    for (int32_t dj = -r; dj <= r && ok; dj++)
                        for (int32_t di = -r; di <= r && ok; di++) {
                            double gx = fmax(abs(di) - 1, 0), gy = fmax(abs(dj) - 1, 0), gz = fmax(abs(dk) - 1, 0);
                            if ((gx * gx + gy * gy + gz * gz) * voxel * voxel >= (double)eps * eps)
                                continue;
                            int64_t x = (int64_t)i + di, y = (int64_t)j + dj, z = (int64_t)k + dk;
                            if (x < 0 || y < 0 || z < 0 || x >= n[0] || y >= n[1] || z >= n[2] ||
                                !solid[VI(x, y, z)])
                                ok = false;
                        }
                kept[VI(i, j, k)] = ok;
            }
    for (uint32_t k = 0; k < n[2] && st == SL_OK; k++)
        for (uint32_t j = 0; j < n[1] && st == SL_OK; j++)
            for (uint32_t i = 0; i < n[0];) {
                if (!kept[VI(i, j, k)]) {
                    i++;
                    continue;
                }
                uint32_t e = i;
                while (e < n[0] && kept[VI(e, j, k)])
                    e++;
                sl_aabb box = {{(float)(b.min.x + (double)i * voxel), (float)(b.min.y + (double)j * voxel),
                                (float)(b.min.z + (double)k * voxel)},
                               {(float)(b.min.x + (double)e * voxel), (float)(b.min.y + (double)(j + 1) * voxel),
                                (float)(b.min.z + (double)(k + 1) * voxel)}};
                if (!sl_array_push(alloc, &out, sizeof box, &box, 1)) {
                    st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory");
                    break;
                }
                i = e;
            }
#undef CI
#undef VI
done:
    sl_free(alloc, inside, corners);
    sl_free(alloc, solid, total);
    sl_free(alloc, kept, total);
    if (st != SL_OK) {
        sl_array_free(alloc, &out, sizeof(sl_aabb));
        return st;
    }
    /* hand out exactly count + 1 boxes' worth, as sl_shrink_boxes_free expects */
    size_t want = (out.count + 1) * sizeof(sl_aabb);
    sl_aabb *res = sl_realloc(alloc, out.data, out.cap * sizeof(sl_aabb), want);
    if (!res) {
        sl_array_free(alloc, &out, sizeof(sl_aabb));
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "shrink: out of memory");
    }
    *boxes = res;
    *count = (uint32_t)out.count;
    return SL_OK;
}

/* Radar echo generation with an object-space occlusion horizon.
 *
 * G. Koldaş, "Efficient Visibility Estimation for Distributed Virtual Urban Environments", PhD
 * thesis, METU 2008, §3.3 (G. Koldaş, V. Çevikbaş, V. İşler, TEHOSS 2006): terrain triangles in a
 * regular grid with per-cell maximum heights and triangles sorted by height; a sweep from the
 * transmitter over the sector, front to back, cell by cell (the cell's conservative elevation is
 * its highest point placed at its nearest distance); visible triangles go to the echo image, drawn
 * top-down. The horizon is the one of the urban cullers (src/cull/urban_internal.h): elevation as
 * slope over pseudo-azimuth bins, partial bins closed when the neighbouring edge arrives.
 *
 * Occluders are the edges of the triangles found visible: the terrain is solid below its surface,
 * so a sight line passing below a point of an edge has gone under the surface. Each visible
 * triangle's edges are inserted once the sweep has passed its farthest point, so a test always
 * sees only occluders nearer than what it tests (a triangle that reaches nearer than the cell
 * being processed is judged by its part inside the cell, and again in its other cells). */
#include "sightline/radar.h"

#include "core/sl_core.h"
#include "cull/urban_internal.h"
#include "sightline/image.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

struct sl_radar_t {
    sl_allocator alloc;
    uint32_t nx, ny;            /* samples */
    double ox, oy, cell;        /* origin and spacing of the samples */
    float *h;                   /* nx*ny heights */
    uint64_t ntri;
    uint32_t gx, gy;            /* grid cells */
    double gcell;               /* grid cell edge */
    uint32_t *start;            /* gx*gy+1 */
    uint32_t *tris;             /* triangles per cell, highest first */
    size_t entries;
    float *cmax;                /* per cell: highest point of its triangles */
    uint8_t *state;             /* per triangle: 0 undecided, 1 visible, 2 hidden, 3 queued for its test */
    sl_horizon hz;
    sl_urban_heap cells, tests, pend; /* by nearest distance; triangles by nearest and by farthest */
};

/* ===== the generated terrain ===================================================================== */

sl_radar_terrain_options sl_radar_terrain_defaults(void)
{
    sl_radar_terrain_options o = {1651, 1401, 40.0f, 900.0f, 1};
    return o;
}

static inline uint32_t mix32(uint64_t x)
{
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdull;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ull;
    x ^= x >> 33;
    return (uint32_t)x;
}

/* Value noise at lattice point (i, j) of octave o, in [0, 1). */
static inline double lattice(int64_t i, int64_t j, uint32_t o, uint64_t seed)
{
    uint64_t k = (uint64_t)i * 0x9E3779B97F4A7C15ull ^ (uint64_t)j * 0xC2B2AE3D27D4EB4Full ^ ((uint64_t)o << 56) ^ seed;
    return mix32(k) * (1.0 / 4294967296.0);
}

static inline double smooth(double t) { return t * t * (3 - 2 * t); }

static double noise(double x, double y, uint32_t o, uint64_t seed)
{
    double fx = floor(x), fy = floor(y);
    int64_t i = (int64_t)fx, j = (int64_t)fy;
    double u = smooth(x - fx), v = smooth(y - fy);
    double a = lattice(i, j, o, seed), b = lattice(i + 1, j, o, seed);
    double c = lattice(i, j + 1, o, seed), d = lattice(i + 1, j + 1, o, seed);
    return a + (b - a) * u + (c - a) * v + (a - b - c + d) * u * v;
}

sl_status sl_radar_terrain_generate(const sl_radar_terrain_options *opt, const sl_allocator *alloc,
                                    sl_terrain_desc *out, sl_error *err)
{
    if (!opt || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar terrain: options and out are required");
    memset(out, 0, sizeof *out);
    if (opt->nx < 2 || opt->ny < 2 || opt->nx > 20000 || opt->ny > 20000)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar terrain: %u x %u samples: each side must be 2..20000",
                       opt->nx, opt->ny);
    if (!(opt->cell > 0) || !isfinite(opt->cell) || !(opt->relief >= 0) || !isfinite(opt->relief))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "radar terrain: cell %g and relief %g must be finite, cell > 0 and relief >= 0", (double)opt->cell,
                       (double)opt->relief);
    size_t n = (size_t)opt->nx * opt->ny;
    float *h = sl_alloc(alloc, n * sizeof(float));
    if (!h)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "radar terrain: out of memory for %zu samples", n);
    /* octaves from a quarter of the longer side down to a few samples; ridged above the second */
    double ext = fmax(opt->nx, opt->ny);
    double base = ext / 4.0;
    uint32_t octaves = 0;
    for (double w = base; w >= 2.0 && octaves < 12; w *= 0.5)
        octaves++;
    float lo = INFINITY, hi = -INFINITY;
    for (uint32_t j = 0; j < opt->ny; j++)
        for (uint32_t i = 0; i < opt->nx; i++) {
            double sum = 0, amp = 1, w = base;
            for (uint32_t o = 0; o < octaves; o++, amp *= 0.5, w *= 0.5) {
                double v = noise(i / w, j / w, o, opt->seed);
                if (o >= 2)
                    v = 1.0 - fabs(2.0 * v - 1.0); /* ridges */
                sum += amp * v;
            }
            /* flatten the lowlands into valleys and plains, keep the peaks sharp */
            float z = (float)(sum * sum);
            h[(size_t)j * opt->nx + i] = z;
            lo = fminf(lo, z);
            hi = fmaxf(hi, z);
        }
    float scale = hi > lo ? opt->relief / (hi - lo) : 0.0f;
    for (size_t k = 0; k < n; k++)
        h[k] = (h[k] - lo) * scale;
    out->nx = opt->nx;
    out->ny = opt->ny;
    out->origin_x = 0;
    out->origin_y = 0;
    out->cell = opt->cell;
    out->heights = h;
    return SL_OK;
}

void sl_radar_terrain_free(sl_terrain_desc *t, const sl_allocator *alloc)
{
    if (!t)
        return;
    sl_free(alloc, (void *)t->heights, (size_t)t->nx * t->ny * sizeof(float));
    memset(t, 0, sizeof *t);
}

/* ===== building ================================================================================== */

sl_radar_options sl_radar_default_options(void)
{
    sl_radar_options o = {100, 16384, NULL};
    return o;
}

/* Vertices of triangle t (x, y, z each). */
static inline void tri_verts(const struct sl_radar_t *r, uint64_t t, double v[3][3])
{
    uint64_t q = t >> 1;
    uint32_t i = (uint32_t)(q % (r->nx - 1)), j = (uint32_t)(q / (r->nx - 1));
    uint32_t ci[3], cj[3];
    if (!(t & 1))
        ci[0] = i, cj[0] = j, ci[1] = i + 1, cj[1] = j, ci[2] = i + 1, cj[2] = j + 1;
    else
        ci[0] = i, cj[0] = j, ci[1] = i + 1, cj[1] = j + 1, ci[2] = i, cj[2] = j + 1;
    for (int k = 0; k < 3; k++) {
        v[k][0] = r->ox + ci[k] * r->cell;
        v[k][1] = r->oy + cj[k] * r->cell;
        v[k][2] = r->h[(size_t)cj[k] * r->nx + ci[k]];
    }
}

static inline float tri_zmax(const struct sl_radar_t *r, uint64_t t)
{
    uint64_t q = t >> 1;
    uint32_t i = (uint32_t)(q % (r->nx - 1)), j = (uint32_t)(q / (r->nx - 1));
    const float *a = r->h + (size_t)j * r->nx + i, *b = a + r->nx;
    float z = fmaxf(a[0], b[1]);
    return fmaxf(z, (t & 1) ? b[0] : a[1]);
}

typedef struct zid {
    float z;
    uint32_t id;
} zid;

static int cmp_zid(const void *a, const void *b)
{
    const zid *p = a, *q = b;
    if (p->z != q->z)
        return p->z > q->z ? -1 : 1;
    return p->id < q->id ? -1 : (p->id > q->id);
}

void sl_radar_destroy(sl_radar r)
{
    if (!r)
        return;
    const sl_allocator *a = &r->alloc;
    size_t nc = (size_t)r->gx * r->gy;
    sl_free(a, r->h, (size_t)r->nx * r->ny * sizeof(float));
    sl_free(a, r->start, (nc + 1) * sizeof(uint32_t));
    sl_free(a, r->tris, (r->entries ? r->entries : 1) * sizeof(uint32_t));
    sl_free(a, r->cmax, (nc ? nc : 1) * sizeof(float));
    sl_free(a, r->state, r->ntri ? r->ntri : 1);
    sl_horizon_free(&r->hz);
    sl_urban_heap_free(&r->cells, a);
    sl_urban_heap_free(&r->pend, a);
    sl_urban_heap_free(&r->tests, a);
    sl_free(a, r, sizeof *r);
}

/* Cell range of the quads [i0, i1] x [j0, j1] (closed boxes: a quad on a cell line is in both). */
static inline void quad_cells(const struct sl_radar_t *r, uint32_t i, uint32_t j, uint32_t *c0, uint32_t *c1,
                              uint32_t *d0, uint32_t *d1)
{
    double x0 = i * r->cell, x1 = (i + 1.0) * r->cell, y0 = j * r->cell, y1 = (j + 1.0) * r->cell;
    double inv = 1.0 / r->gcell;
    *c0 = (uint32_t)fmin(floor(x0 * inv), r->gx - 1.0);
    *c1 = (uint32_t)fmin(floor(x1 * inv), r->gx - 1.0);
    *d0 = (uint32_t)fmin(floor(y0 * inv), r->gy - 1.0);
    *d1 = (uint32_t)fmin(floor(y1 * inv), r->gy - 1.0);
}

sl_status sl_radar_create(const sl_terrain_desc *t, const sl_radar_options *opt, sl_radar *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: out is NULL");
    *out = NULL;
    sl_radar_options o = opt ? *opt : sl_radar_default_options();
    if (!t || !t->heights)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: no terrain");
    if (t->nx < 2 || t->ny < 2 || t->nx > 65536 || t->ny > 65536 || (uint64_t)(t->nx - 1) * (t->ny - 1) * 2 > UINT32_MAX)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: terrain of %u x %u samples: each side must be 2..65536 "
                                                       "and the triangles fewer than 2^32", t->nx, t->ny);
    if (!(t->cell > 0) || !isfinite(t->cell) || !isfinite(t->origin_x) || !isfinite(t->origin_y))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: terrain spacing %g and origin (%g, %g) must be finite, "
                                                       "spacing > 0", (double)t->cell, (double)t->origin_x,
                       (double)t->origin_y);
    if (o.grid < 2 || o.grid > 4096)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: grid %u must be 2..4096", o.grid);
    if (o.bins < 1024 || o.bins > (1u << 20))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: bins %u must be 1024..1048576", o.bins);
    size_t n = (size_t)t->nx * t->ny;
    for (size_t k = 0; k < n; k++)
        if (!isfinite(t->heights[k]) || fabsf(t->heights[k]) > 1e7f)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: terrain height %zu (sample %zu, %zu) is %g: not finite "
                                                           "or beyond 1e7", k, k % t->nx, k / t->nx,
                           (double)t->heights[k]);
    const sl_allocator *a = sl_alloc_or_default(o.alloc);
    struct sl_radar_t *r = sl_calloc(a, 1, sizeof *r);
    if (!r)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "radar: out of memory");
    r->alloc = *a;
    a = &r->alloc;
    r->nx = t->nx, r->ny = t->ny;
    r->ox = t->origin_x, r->oy = t->origin_y, r->cell = t->cell;
    r->ntri = 2ull * (t->nx - 1) * (t->ny - 1);
    double ex = (t->nx - 1.0) * t->cell, ey = (t->ny - 1.0) * t->cell;
    r->gcell = fmax(ex, ey) / o.grid;
    r->gx = (uint32_t)fmax(1.0, ceil(ex / r->gcell - 1e-9));
    r->gy = (uint32_t)fmax(1.0, ceil(ey / r->gcell - 1e-9));
    size_t nc = (size_t)r->gx * r->gy;
    r->h = sl_alloc(a, n * sizeof(float));
    r->start = sl_calloc(a, nc + 1, sizeof(uint32_t));
    r->cmax = sl_alloc(a, nc * sizeof(float));
    r->state = sl_alloc(a, r->ntri);
    sl_status st = SL_OK;
    if (!r->h || !r->start || !r->cmax || !r->state)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "radar: out of memory for %llu triangles",
                     (unsigned long long)r->ntri);
    if (st == SL_OK)
        memcpy(r->h, t->heights, n * sizeof(float));
    /* bucket: count, then fill, every triangle into each cell its quad's box touches */
    const uint32_t qx = t->nx - 1, qy = t->ny - 1;
    if (st == SL_OK) {
        for (uint32_t j = 0; j < qy; j++)
            for (uint32_t i = 0; i < qx; i++) {
                uint32_t c0, c1, d0, d1;
                quad_cells(r, i, j, &c0, &c1, &d0, &d1);
                for (uint32_t d = d0; d <= d1; d++)
                    for (uint32_t c = c0; c <= c1; c++)
                        r->start[(size_t)d * r->gx + c + 1] += 2;
            }
        for (size_t c = 0; c < nc; c++)
            r->start[c + 1] += r->start[c];
        r->entries = r->start[nc];
        r->tris = sl_alloc(a, (r->entries ? r->entries : 1) * sizeof(uint32_t));
        uint32_t *fill = sl_alloc(a, nc * sizeof(uint32_t));
        if (!r->tris || !fill)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "radar: out of memory for %zu cell entries", r->entries);
        else {
            memcpy(fill, r->start, nc * sizeof(uint32_t));
            for (uint32_t j = 0; j < qy; j++)
                for (uint32_t i = 0; i < qx; i++) {
                    uint32_t c0, c1, d0, d1, q = j * qx + i;
                    quad_cells(r, i, j, &c0, &c1, &d0, &d1);
                    for (uint32_t d = d0; d <= d1; d++)
                        for (uint32_t c = c0; c <= c1; c++) {
                            size_t cc = (size_t)d * r->gx + c;
                            r->tris[fill[cc]++] = 2 * q;
                            r->tris[fill[cc]++] = 2 * q + 1;
                        }
                }
        }
        sl_free(a, fill, nc * sizeof(uint32_t));
    }
    /* each cell's triangles from the highest down, and its highest point */
    if (st == SL_OK) {
        size_t most = 0;
        for (size_t c = 0; c < nc; c++)
            most = SL_MAX(most, (size_t)(r->start[c + 1] - r->start[c]));
        zid *tmp = sl_alloc(a, (most ? most : 1) * sizeof(zid));
        if (!tmp)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "radar: out of memory");
        for (size_t c = 0; c < nc && st == SL_OK; c++) {
            uint32_t b = r->start[c], m = r->start[c + 1] - b;
            for (uint32_t k = 0; k < m; k++)
                tmp[k] = (zid){tri_zmax(r, r->tris[b + k]), r->tris[b + k]};
            qsort(tmp, m, sizeof(zid), cmp_zid);
            for (uint32_t k = 0; k < m; k++)
                r->tris[b + k] = tmp[k].id;
            r->cmax[c] = m ? tmp[0].z : -INFINITY;
        }
        sl_free(a, tmp, (most ? most : 1) * sizeof(zid));
    }
    if (st == SL_OK)
        st = sl_horizon_init(&r->hz, o.bins, false, a, err);
    if (st == SL_OK)
        st = sl_urban_heap_init(&r->cells, (uint32_t)nc, a, err);
    if (st == SL_OK)
        st = sl_urban_heap_init(&r->pend, (uint32_t)r->ntri, a, err);
    if (st == SL_OK)
        st = sl_urban_heap_init(&r->tests, (uint32_t)r->ntri, a, err);
    if (st != SL_OK) {
        sl_radar_destroy(r);
        return st;
    }
    memset(r->state, 0, r->ntri);
    *out = r;
    return SL_OK;
}

uint64_t sl_radar_triangle_count(sl_radar r) { return r ? r->ntri : 0; }

void sl_radar_grid_size(sl_radar r, uint32_t *gx, uint32_t *gy)
{
    if (gx)
        *gx = r ? r->gx : 0;
    if (gy)
        *gy = r ? r->gy : 0;
}

/* Height on the triangles at grid coordinates (u, v) (in samples), clamped. */
static double height_uv(const struct sl_radar_t *r, double u, double v)
{
    double mu = r->nx - 1.0, mv = r->ny - 1.0;
    u = u < 0 ? 0 : (u > mu ? mu : u);
    v = v < 0 ? 0 : (v > mv ? mv : v);
    uint32_t i = (uint32_t)fmin(floor(u), mu - 1), j = (uint32_t)fmin(floor(v), mv - 1);
    double fu = u - i, fv = v - j;
    const float *a = r->h + (size_t)j * r->nx + i, *b = a + r->nx;
    if (fu >= fv)
        return a[0] + fu * (a[1] - a[0]) + fv * (b[1] - a[1]);
    return a[0] + fv * (b[0] - a[0]) + fu * (b[1] - b[0]);
}

float sl_radar_height(sl_radar r, float x, float y)
{
    if (!r || !isfinite(x) || !isfinite(y))
        return 0;
    return (float)height_uv(r, (x - r->ox) / r->cell, (y - r->oy) / r->cell);
}

/* ===== the sweep ================================================================================= */

bool sl_radar_visible(sl_radar r, uint64_t t) { return r && t < r->ntri && r->state[t] == 1; }

/* Cell rectangle. */
static inline void cell_rect(const struct sl_radar_t *r, uint32_t c, double q[4])
{
    uint32_t i = c % r->gx, j = c / r->gx;
    q[0] = r->ox + i * r->gcell;
    q[1] = r->oy + j * r->gcell;
    q[2] = r->ox + (i + 1.0) * r->gcell;
    q[3] = r->oy + (j + 1.0) * r->gcell;
}

static inline float key_down(double d)
{
    float f = (float)d;
    if ((double)f > d)
        f -= fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

static inline float key_up(double d)
{
    float f = (float)d;
    if ((double)f < d)
        f += fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

typedef struct sector {
    bool full;
    double p0, pspan;           /* pseudo-azimuths */
    double range;
} sector;

static inline bool sector_meets(const sector *s, double a0, double span)
{
    if (s->full || span >= SL_URBAN_CIRCLE)
        return true;
    double d = sl_urban_paz_wrap(a0 - s->p0);
    return d <= s->pspan || d + span >= SL_URBAN_CIRCLE;
}

static sl_status make_sector(const sl_radar_sweep *sw, sector *s, sl_error *err)
{
    if (!isfinite(sw->transmitter.x) || !isfinite(sw->transmitter.y) || !isfinite(sw->transmitter.z) ||
        !isfinite(sw->azimuth) || !(sw->width > 0) || !(sw->width <= 6.2832f) || !(sw->range > 0))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "radar: sweep: the transmitter and azimuth must be finite, the width in (0, 2 pi], the range > 0");
    s->full = sw->width >= 6.2831f;
    s->range = sw->range;
    if (!s->full) {
        double a = sw->azimuth, b = (double)sw->azimuth + sw->width;
        /* a hair wider, for the rounding of the angles */
        s->p0 = sl_urban_paz(cos(a - 1e-7), sin(a - 1e-7));
        s->pspan = sl_urban_paz_wrap(sl_urban_paz(cos(b + 1e-7), sin(b + 1e-7)) - s->p0);
        if (sw->width > 3.14159f && s->pspan < 2.0)
            s->pspan = SL_URBAN_CIRCLE; /* rounding turned a wide sector around: take it all */
    }
    return SL_OK;
}

/* Insert the edges of a visible triangle into the horizon. */
static void insert_triangle(struct sl_radar_t *r, const double eye[3], uint64_t t)
{
    double v[3][3];
    tri_verts(r, t, v);
    for (int k = 0; k < 3; k++) {
        const double *p = v[k], *q = v[(k + 1) % 3];
        sl_horizon_seg s = {p[0], p[1], p[2], q[0], q[1], q[2], -INFINITY};
        sl_horizon_insert(&r->hz, eye, &s);
    }
}

sl_status sl_radar_run(sl_radar r, const sl_radar_sweep *sw, sl_radar_stats *stats, sl_error *err)
{
    if (!r || !sw)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: radar and sweep are required");
    sector sec;
    sl_status st = make_sector(sw, &sec, err);
    if (st != SL_OK)
        return st;
    const double eye[3] = {sw->transmitter.x, sw->transmitter.y, sw->transmitter.z};
    double ground = height_uv(r, (eye[0] - r->ox) / r->cell, (eye[1] - r->oy) / r->cell);
    if (!(eye[2] > ground))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "radar: the transmitter at (%g, %g, %g) is not above the terrain (%g there)", eye[0], eye[1],
                       eye[2], ground);
    double t0 = sl_now();
    sl_radar_stats s;
    memset(&s, 0, sizeof s);
    memset(r->state, 0, r->ntri);
    sl_horizon_reset(&r->hz);
    r->cells.n = r->pend.n = r->tests.n = 0;
    const size_t nc = (size_t)r->gx * r->gy;
    for (size_t c = 0; c < nc; c++) {
        if (r->cmax[c] == -INFINITY)
            continue;
        double q[4], dmin, dmax, a0, span;
        cell_rect(r, (uint32_t)c, q);
        sl_urban_rect_dist(eye, q[0], q[1], q[2], q[3], &dmin, &dmax);
        if (dmin > sec.range)
            continue;
        if (!sl_urban_rect_az(eye, q[0], q[1], q[2], q[3], &a0, &span))
            span = SL_URBAN_CIRCLE;
        if (!sector_meets(&sec, a0, span))
            continue;
        sl_urban_heap_push(&r->cells, key_down(dmin), (uint32_t)c);
    }
    /* events in order of distance: cells at their nearest point, triangle tests at the triangle's
     * nearest point; before each, the visible triangles entirely nearer go into the horizon */
    while (r->cells.n || r->tests.n) {
        bool is_test = r->tests.n && (!r->cells.n || r->tests.key[0] <= r->cells.key[0]);
        float key = is_test ? r->tests.key[0] : r->cells.key[0];
        while (r->pend.n && r->pend.key[0] <= key)
            insert_triangle(r, eye, sl_urban_heap_pop(&r->pend));
        if (is_test) {
            uint32_t t = sl_urban_heap_pop(&r->tests);
            double v[3][3];
            tri_verts(r, t, v);
            double b[4] = {fmin(v[0][0], fmin(v[1][0], v[2][0])), fmin(v[0][1], fmin(v[1][1], v[2][1])),
                           fmax(v[0][0], fmax(v[1][0], v[2][0])), fmax(v[0][1], fmax(v[1][1], v[2][1]))};
            double tdmin, tdmax, ta0, tspan;
            sl_urban_rect_dist(eye, b[0], b[1], b[2], b[3], &tdmin, &tdmax);
            if (!sl_urban_rect_az(eye, b[0], b[1], b[2], b[3], &ta0, &tspan))
                tspan = SL_URBAN_CIRCLE;
            s.triangles_tested++;
            double th = sl_urban_slope_hi(tri_zmax(r, t), eye[2], tdmin, tdmax);
            if (sector_meets(&sec, ta0, tspan) && !sl_horizon_occluded(&r->hz, ta0, tspan, th, -INFINITY)) {
                r->state[t] = 1;
                s.triangles_visible++;
                sl_urban_heap_push(&r->pend, key_up(tdmax), t);
            } else
                r->state[t] = 2;
            continue;
        }
        uint32_t c = sl_urban_heap_pop(&r->cells);
        double q[4], dmin, dmax, a0, span;
        cell_rect(r, c, q);
        sl_urban_rect_dist(eye, q[0], q[1], q[2], q[3], &dmin, &dmax);
        if (!sl_urban_rect_az(eye, q[0], q[1], q[2], q[3], &a0, &span))
            span = SL_URBAN_CIRCLE;
        s.cells_tested++;
        double hi = sl_urban_slope_hi(r->cmax[c], eye[2], dmin, dmax);
        if (sl_horizon_occluded(&r->hz, a0, span, hi, -INFINITY)) {
            s.cells_culled++;
            continue;
        }
        double min_h, max_b;
        sl_horizon_range(&r->hz, a0, span, &min_h, &max_b);
        const double stop = min_h - 1e-6 * (1 + fabs(min_h));
        for (uint32_t k = r->start[c]; k < r->start[c + 1]; k++) {
            uint32_t t = r->tris[k];
            float zt = tri_zmax(r, t);
            /* highest first: once one is below the horizon over the whole cell, so is the rest */
            if (sl_urban_slope_hi(zt, eye[2], dmin, dmax) < stop)
                break;
            if (r->state[t])
                continue;
            double v[3][3];
            tri_verts(r, t, v);
            double b[4] = {fmin(v[0][0], fmin(v[1][0], v[2][0])), fmin(v[0][1], fmin(v[1][1], v[2][1])),
                           fmax(v[0][0], fmax(v[1][0], v[2][0])), fmax(v[0][1], fmax(v[1][1], v[2][1]))};
            double tdmin, tdmax;
            sl_urban_rect_dist(eye, b[0], b[1], b[2], b[3], &tdmin, &tdmax);
            if (tdmin > sec.range) {
                r->state[t] = 2; /* beyond the range */
                continue;
            }
            if (tdmin >= (double)key) {
                /* test it when the sweep reaches it, with every occluder nearer than it */
                r->state[t] = 3;
                sl_urban_heap_push(&r->tests, key_down(tdmin), t);
                continue;
            }
            /* it reaches nearer than this cell: judge its part inside the cell now */
            double tb[4] = {fmax(b[0], q[0]), fmax(b[1], q[1]), fmin(b[2], q[2]), fmin(b[3], q[3])};
            if (tb[0] > tb[2] || tb[1] > tb[3])
                continue;
            double rdmin, rdmax, ta0, tspan;
            sl_urban_rect_dist(eye, tb[0], tb[1], tb[2], tb[3], &rdmin, &rdmax);
            if (!sl_urban_rect_az(eye, tb[0], tb[1], tb[2], tb[3], &ta0, &tspan))
                tspan = SL_URBAN_CIRCLE;
            if (!sector_meets(&sec, ta0, tspan))
                continue;
            s.triangles_tested++;
            double th = sl_urban_slope_hi(zt, eye[2], rdmin, rdmax);
            if (!sl_horizon_occluded(&r->hz, ta0, tspan, th, -INFINITY)) {
                r->state[t] = 1;
                s.triangles_visible++;
                sl_urban_heap_push(&r->pend, key_up(tdmax), t);
            }
        }
    }
    s.bins_written = r->hz.bins_written;
    s.ms = (sl_now() - t0) * 1e3;
    if (stats)
        *stats = s;
    return SL_OK;
}

/* ===== exact line of sight ======================================================================== */

bool sl_radar_line_of_sight(sl_radar r, sl_vec3 a, sl_vec3 b, double tol)
{
    if (!r)
        return false;
    double ua = (a.x - r->ox) / r->cell, va = (a.y - r->oy) / r->cell;
    double ub = (b.x - r->ox) / r->cell, vb = (b.y - r->oy) / r->cell;
    double du = ub - ua, dv = vb - va, dz = (double)b.z - a.z;
    double len = sqrt((du * du + dv * dv) * r->cell * r->cell + dz * dz);
    double tmax = len > 0 ? 1.0 - tol / len : 0.0;
    /* the surface and the segment are both linear between crossings of the lines u = k, v = k and
     * u - v = k (the quads' edges and diagonals): checking at every crossing is exact */
    for (int fam = 0; fam < 3; fam++) {
        double s0 = fam == 0 ? ua : (fam == 1 ? va : ua - va);
        double ds = fam == 0 ? du : (fam == 1 ? dv : du - dv);
        if (ds == 0)
            continue;
        double lo = fmin(s0, s0 + ds), hi = fmax(s0, s0 + ds);
        for (double k = ceil(lo); k <= hi; k += 1.0) {
            double t = (k - s0) / ds;
            if (t <= 0 || t > tmax)
                continue;
            double z = a.z + t * dz;
            if (height_uv(r, ua + t * du, va + t * dv) > z + tol)
                return false;
        }
    }
    return true;
}

/* ===== the echo image ============================================================================= */

sl_status sl_radar_echo_png(sl_radar r, const sl_radar_sweep *sw, const char *path, uint32_t width, uint32_t height,
                            sl_error *err)
{
    if (!r || !sw || !path)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: radar, sweep and path are required");
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "radar: image %u x %u: each side must be 1..16384", width,
                       height);
    sector sec;
    sl_status st = make_sector(sw, &sec, err);
    if (st != SL_OK)
        return st;
    uint8_t *img = sl_alloc(&r->alloc, (size_t)width * height * 3);
    if (!img)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "radar: out of memory for a %u x %u image", width, height);
    const double ex = (r->nx - 1.0) * r->cell, ey = (r->ny - 1.0) * r->cell;
    const double tx = sw->transmitter.x, ty = sw->transmitter.y, tz = sw->transmitter.z;
    for (uint32_t py = 0; py < height; py++)
        for (uint32_t px = 0; px < width; px++) {
            double u = (px + 0.5) / width * (r->nx - 1.0), v = (1.0 - (py + 0.5) / height) * (r->ny - 1.0);
            uint32_t i = (uint32_t)fmin(floor(u), r->nx - 2.0), j = (uint32_t)fmin(floor(v), r->ny - 2.0);
            uint64_t t = 2ull * ((uint64_t)j * (r->nx - 1) + i) + (u - i >= v - j ? 0 : 1);
            double vt[3][3];
            tri_verts(r, t, vt);
            /* the triangle's normal, lit from the transmitter and, dimly, from the north-west */
            double e1[3] = {vt[1][0] - vt[0][0], vt[1][1] - vt[0][1], vt[1][2] - vt[0][2]};
            double e2[3] = {vt[2][0] - vt[0][0], vt[2][1] - vt[0][1], vt[2][2] - vt[0][2]};
            double nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            double nl = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
            double x = r->ox + u * r->cell, y = r->oy + v * r->cell, z = height_uv(r, u, v);
            double dx = tx - x, dy = ty - y, dz = tz - z, dl = sqrt(dx * dx + dy * dy + dz * dz);
            uint8_t *p = img + 3 * ((size_t)py * width + px);
            double pa = sl_urban_paz(x - tx, y - ty);
            bool inside = hypot(x - tx, y - ty) <= sec.range && sector_meets(&sec, pa, 0.0);
            if (!inside) {
                p[0] = p[1] = p[2] = 0;
                continue;
            }
            if (r->state[t] == 1) {
                double c = nl > 0 && dl > 0 ? (nrm[0] * dx + nrm[1] * dy + nrm[2] * dz) / (nl * dl) : 0;
                c = c < 0 ? 0 : c;
                p[0] = (uint8_t)(20 + 60 * c);
                p[1] = (uint8_t)(70 + 185 * c);
                p[2] = (uint8_t)(20 + 40 * c);
            } else {
                double c = nl > 0 ? (nrm[0] * -0.5 + nrm[1] * 0.5 + nrm[2] * 0.7) / (nl * 0.9945) : 0;
                c = c < 0 ? 0 : c;
                uint8_t g = (uint8_t)(18 + 30 * c);
                p[0] = g, p[1] = g, p[2] = (uint8_t)(g + 10);
            }
        }
    /* the transmitter */
    int32_t cx = (int32_t)floor((tx - r->ox) / ex * width), cy = (int32_t)floor((1.0 - (ty - r->oy) / ey) * height);
    for (int32_t d = -3; d <= 3; d++)
        for (int32_t e = -3; e <= 3; e++) {
            int32_t x = cx + d, y = cy + e;
            if (x >= 0 && y >= 0 && (uint32_t)x < width && (uint32_t)y < height) {
                uint8_t *p = img + 3 * ((size_t)y * width + (uint32_t)x);
                p[0] = 255, p[1] = 40, p[2] = 40;
            }
        }
    st = sl_png_write(path, width, height, 3, img, 0, err);
    sl_free(&r->alloc, img, (size_t)width * height * 3);
    return st;
}

/* Conservative top-down rasterization of occluder shadows into a cull map with max merging.
 *
 * P. Wonka, "Occlusion Culling for Real-Time Rendering of Urban Environments", PhD thesis, TU Wien
 * 2001, §4.2.1 (occluder shadows), §4.3.4 (sampling correction: inward shift of the shadow's edges
 * by l(|nx|+|ny|) so that centre sampling only covers fully shadowed cells, with the lowest height
 * over the cell). The seam rule that keeps the shadows of connected façades free of cracks is ours
 * (the thesis builds crack-free shadows from shrunk footprints, §4.4): see cullmap_raster.h.
 *
 * Every test is done on the cell centre with linear functions in double precision:
 *   behind(X) = distance of X behind the edge line minus l(|nx|+|ny|)    >= 0: cell behind the edge
 *   ray_a(X), ray_b(X) = signed distances to the side rays, positive inside the wedge
 *   top(X)    = top plane at X minus l(|Px|+|Py|)                  = minimum over the cell
 *   bottom(X) = bottom plane at X plus l(|Qx|+|Qy|)                = maximum over the cell
 * where l is half the cell plus the map's margin. A linear function's extremes over a square are
 * at its corners, and a square of half side l crosses a line of unit normal n exactly when the
 * centre is within l(|nx|+|ny|) of it, so each test is exact for the (slightly enlarged) cell. */
#include "cullmap_raster.h"

#include <float.h>
#include <math.h>
#include <string.h>

typedef struct lin {
    double c, cx, cy; /* c + cx*x + cy*y */
    double inv;       /* 1 / cx (0 when cx is 0), for solving rows */
} lin;

static inline double lin_at(const lin *f, double x, double y) { return f->c + f->cx * x + f->cy * y; }
static inline double dmin2(double a, double b) { return a < b ? a : b; }

/* Per-edge functions for one eye. */
typedef struct wedge {
    bool ok;
    lin behind, ray_a, ray_b, top, bottom;
    double eps_a, eps_b; /* l(|nx|+|ny|) of the side rays */
    double base;
    bool bottom_easy;    /* eye at or above the base: the bottom plane is <= base behind the edge */
    float easy_floor;    /* a floor at or above this needs no bottom test (INFINITY: every floor does) */
} wedge;

static wedge make_wedge(const sl_shadow_edge *e, const double eye[3], double l)
{
    wedge w;
    memset(&w, 0, sizeof w);
    double ox = eye[0], oy = eye[1], oz = eye[2];
    double ax = e->ax - ox, ay = e->ay - oy, bx = e->bx - ox, by = e->by - oy;
    double la = hypot(ax, ay), lb = hypot(bx, by);
    double cr = ax * by - ay * bx; /* < 0: a->b turns clockwise seen from the eye (eye in front) */
    double dx = e->bx - e->ax, dy = e->by - e->ay, len = hypot(dx, dy);
    if (!(la > 0) || !(lb > 0) || !(len > 0) || !(cr < -1e-12 * la * lb) || !isfinite(cr))
        return w;
    /* behind the edge line: -n.(X - a) with n = (dy, -dx)/len the outward normal (eye side) */
    double eps_e = l * (fabs(dx) + fabs(dy)) / len;
    w.behind.cx = -dy / len;
    w.behind.cy = dx / len;
    w.behind.c = -(w.behind.cx * e->ax + w.behind.cy * e->ay) - eps_e;
    /* side rays through the eye: interior is clockwise from a and counter-clockwise from b */
    w.ray_a.cx = ay / la;
    w.ray_a.cy = -ax / la;
    w.ray_a.c = -(w.ray_a.cx * ox + w.ray_a.cy * oy);
    w.eps_a = l * (fabs(ax) + fabs(ay)) / la;
    w.ray_b.cx = -by / lb;
    w.ray_b.cy = bx / lb;
    w.ray_b.c = -(w.ray_b.cx * ox + w.ray_b.cy * oy);
    w.eps_b = l * (fabs(bx) + fabs(by)) / lb;
    /* planes through the eye and the top (bottom) edge: normal (A-O)x(B-O), whose z is cr */
    double az = e->az - oz, bz = e->bz - oz;
    double nx = ay * bz - az * by, ny = az * bx - ax * bz;
    w.top.cx = -nx / cr;
    w.top.cy = -ny / cr;
    w.top.c = oz - w.top.cx * ox - w.top.cy * oy - l * (fabs(w.top.cx) + fabs(w.top.cy));
    double hz = e->base - oz;
    double qx = ay * hz - hz * by, qy = hz * bx - ax * hz;
    w.bottom.cx = -qx / cr;
    w.bottom.cy = -qy / cr;
    w.bottom.c = oz - w.bottom.cx * ox - w.bottom.cy * oy + l * (fabs(w.bottom.cx) + fabs(w.bottom.cy));
    w.base = e->base;
    w.bottom_easy = oz >= e->base;
    w.easy_floor = INFINITY; /* set below, once float_up is known */
    w.ok = isfinite(w.top.c) && isfinite(w.top.cx) && isfinite(w.top.cy) && isfinite(w.bottom.c) &&
           isfinite(w.bottom.cx) && isfinite(w.bottom.cy);
    lin *ls[5] = {&w.behind, &w.ray_a, &w.ray_b, &w.top, &w.bottom};
    for (int k = 0; k < 5; k++)
        ls[k]->inv = ls[k]->cx != 0 ? 1.0 / ls[k]->cx : 0.0;
    return w;
}

/* Pseudo-azimuth of a direction: increasing with the azimuth, in [0, 4), no trigonometry (the
 * "diamond angle"; the urban cullers use the same function). */
static inline double paz(double dx, double dy)
{
    if (dy >= 0)
        return dx >= 0 ? (dx + dy > 0 ? dy / (dx + dy) : 0.0) : 1.0 + -dx / (dy - dx);
    return dx < 0 ? 2.0 + -dy / (-dx - dy) : 3.0 + dx / (dx - dy);
}

static inline double paz_wrap(double p)
{
    if (!(p >= -4.0 && p < 8.0)) /* (differences of pseudo-azimuths are in (-4, 4)) */
        p = fmod(p, 4.0);
    else if (p >= 4.0)
        p -= 4.0; /* exact, as fmod */
    if (p < 0)
        p += 4.0;
    return p >= 4.0 ? 0.0 : p;
}

static inline float f_down(double v)
{
    float f = (float)v;
    if ((double)f > v)
        f -= fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

static inline float f_up(double v)
{
    float f = (float)v;
    if ((double)f < v)
        f += fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

/* Cell (i, j) reaches its highest point: one fewer unsaturated cell in its block, and its bits
 * cleared (the band's when no other cell of its column in the band is left). */
static void saturate(const sl_cullmap_grid *map, uint32_t i, uint32_t j)
{
    const uint32_t bs = map->block_shift > 6 ? 6 : map->block_shift;
    if (map->unsat)
        map->unsat[(size_t)(j >> bs) * map->bnx + (i >> bs)]--;
    if (map->row_bits) {
        map->row_bits[(size_t)j * map->words + (i >> 6)] &= ~(1ull << (i & 63));
        uint8_t *cnt = &map->band_count[(size_t)(j >> bs) * map->nx + i];
        if (*cnt && --*cnt == 0)
            map->band_bits[(size_t)(j >> bs) * map->words + (i >> 6)] &= ~(1ull << (i & 63));
    }
}

/* Raise cell (i, j) of row zrow to f if higher (max merge, saturation bookkeeping). Returns 1 if
 * raised. */
static inline uint64_t raise_cell(const sl_cullmap_grid *map, float *zrow, const float *trow, uint32_t i, uint32_t j,
                                  float f)
{
    if (!(f > zrow[i]))
        return 0;
    if (trow && zrow[i] < trow[i] && f >= trow[i])
        saturate(map, i, j);
    zrow[i] = f;
    return 1;
}

/* The value written for a shadow plane value v: below v by the allowance, whatever the float
 * rounding. */
static inline float cell_float(double v) { return (float)(v - 1e-4 - fabs(v) * 2.4e-7); }

/* Cell (i, j), wholly behind the edge of a shadow whose azimuths are [pb, pa] (pseudo), straddles
 * the shadow's silhouette ray a (sa) and/or b (sb): record the covered part of the cell's azimuth
 * range with the shadow's value v over the cell; when the recorded parts meet, write the cell. */
static uint64_t partial(const sl_cullmap_grid *map, const double eye[3], uint32_t i, uint32_t j, double l, double pa,
                        double pb, bool sa, bool sb, double v, float *zrow, const float *trow)
{
    double cx = map->min_x + (i + 0.5) * map->cell, cy = map->min_y + (j + 0.5) * map->cell;
    double x0 = cx - l - eye[0], x1 = cx + l - eye[0], y0 = cy - l - eye[1], y1 = cy + l - eye[1];
    if (x0 <= 0 && x1 >= 0 && y0 <= 0 && y1 >= 0)
        return 0;
    /* the cell's azimuth range [c0, c0 + cs]: its two tangent corners */
    double px, py, qx, qy;
    if (x1 < 0) {
        if (y1 < 0)
            px = x0, py = y1, qx = x1, qy = y0;
        else if (y0 > 0)
            px = x1, py = y1, qx = x0, qy = y0;
        else
            px = x1, py = y1, qx = x1, qy = y0;
    } else if (x0 > 0) {
        if (y1 < 0)
            px = x0, py = y0, qx = x1, qy = y1;
        else if (y0 > 0)
            px = x1, py = y0, qx = x0, qy = y1;
        else
            px = x0, py = y0, qx = x0, qy = y1;
    } else if (y1 < 0)
        px = x0, py = y1, qx = x1, qy = y1;
    else
        px = x1, py = y0, qx = x0, qy = y0;
    double c0 = paz(px, py), cs = paz_wrap(paz(qx, qy) - c0);
    double ra = paz_wrap(pa - c0), rb = paz_wrap(pb - c0);
    sl_cullmap_part *st = &map->part[(size_t)j * map->nx + i];
    if (st->stamp != map->stamp) {
        st->stamp = map->stamp;
        st->l_end = -1.0f, st->l_val = INFINITY, st->r_start = INFINITY, st->r_val = INFINITY;
    }
    float fv = f_down(v);
    if (sa && !sb) { /* covered from the cell's first azimuth up to ray a */
        if (!(ra <= cs))
            return 0;
        float e = f_down(ra);
        if (e > st->l_end)
            st->l_end = e, st->l_val = fv;
    } else if (sb && !sa) { /* from ray b to the cell's last azimuth */
        if (!(rb <= cs))
            return 0;
        float b = f_up(rb);
        if (b < st->r_start)
            st->r_start = b, st->r_val = fv;
    } else { /* a middle part: it can only extend a part it overlaps */
        if (!(rb < ra && ra <= cs))
            return 0;
        float b = f_up(rb), e = f_down(ra);
        if (st->l_end >= 0 && b <= st->l_end && e > st->l_end)
            st->l_end = e, st->l_val = fminf(st->l_val, fv);
        if (st->r_start <= 4.0f && e >= st->r_start && b < st->r_start)
            st->r_start = b, st->r_val = fminf(st->r_val, fv);
    }
    if (st->l_end >= 0 && st->r_start <= 4.0f && st->l_end >= st->r_start)
        return raise_cell(map, zrow, trow, i, j, cell_float(fmin((double)st->l_val, (double)st->r_val)));
    return 0;
}

/* One row's cells for the wedge: [i0, i1] to test, [f0, f1] needing only the value. */
typedef struct row_span {
    int32_t i0, i1, f0, f1;
    double y, vrow;
} row_span;

/* Does the edge face the eye (make_wedge would accept it)? */
static inline bool faces(const sl_shadow_edge *e, const double eye[3])
{
    double ax = e->ax - eye[0], ay = e->ay - eye[1], bx = e->bx - eye[0], by = e->by - eye[1];
    double cr = ax * by - ay * bx;
    return cr < -1e-12 * sqrt((ax * ax + ay * ay) * (bx * bx + by * by)) && (e->ax != e->bx || e->ay != e->by);
}

/* Is the wedge's shadow valid for everything in a cell with this floor (nothing below the bottom
 * plane)? */
static inline bool bottom_ok(const wedge *w, float floor, double x, double y)
{
    if (w->bottom_easy && (double)floor >= w->base)
        return true;
    return lin_at(&w->bottom, x, y) <= (double)floor;
}

/* A float not below v (one rounding is below 2^-24 relative; step by 2^-23 plus the smallest
 * normal, without a libm call). */
static inline float float_up(double v)
{
    float f = (float)v;
    if ((double)f < v)
        f += fabsf(f) * 1.2e-7f + FLT_MIN;
    return f;
}

/* Clip a convex polygon by f >= 0 (Sutherland-Hodgman). */
static int clip_poly(const double (*in)[2], int n, const lin *f, double bound, double (*out)[2])
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        const double *p = in[i], *q = in[(i + 1) % n];
        double fp = lin_at(f, p[0], p[1]) - bound, fq = lin_at(f, q[0], q[1]) - bound;
        if (fp >= 0) {
            out[m][0] = p[0];
            out[m][1] = p[1];
            m++;
        }
        if ((fp >= 0) != (fq >= 0)) {
            double t = fp / (fp - fq);
            out[m][0] = p[0] + t * (q[0] - p[0]);
            out[m][1] = p[1] + t * (q[1] - p[1]);
            m++;
        }
    }
    return m;
}

/* The lines bounding the rows' cell ranges, sorted once per wedge by the side they bound, so that
 * the rows need no branch: x >= -(c + cy y - bound) / cx where cx > 0, x <= that where cx < 0, and
 * the row is empty where c + cy y - bound < 0 for cx = 0 (f(x, y) >= bound solved for x). */
typedef struct bline {
    double c, cy, bound, inv;
} bline;

typedef struct blines {
    uint32_t nl, nu, nz;
    bline l[4], u[4], z[4];
} blines;

static void blines_add(blines *b, const lin *f, double bound)
{
    bline q = {f->c, f->cy, bound, f->inv};
    if (f->cx > 0)
        b->l[b->nl++] = q;
    else if (f->cx < 0)
        b->u[b->nu++] = q;
    else
        b->z[b->nz++] = q;
}

static inline double bline_x(const bline *q, double y) { return -(q->c + q->cy * y - q->bound) * q->inv; }

/* Narrow [*lo, *hi] to the x where f(x, y) >= bound for every line. */
static inline void blines_narrow(const blines *b, double y, double *lo, double *hi)
{
    double xl = *lo, xr = *hi;
    for (uint32_t k = 0; k < b->nl; k++) {
        double x = bline_x(&b->l[k], y);
        xl = x > xl ? x : xl;
    }
    for (uint32_t k = 0; k < b->nu; k++) {
        double x = bline_x(&b->u[k], y);
        xr = x < xr ? x : xr;
    }
    for (uint32_t k = 0; k < b->nz; k++)
        if (b->z[k].c + b->z[k].cy * y - b->z[k].bound < 0)
            xr = -INFINITY;
    *lo = xl;
    *hi = xr;
}

/* Bounds of the x where the lines may all hold for some y in [ya, yb]: per line the looser of its
 * bounds at the two ends (the lines are linear in y). */
static inline void blines_band(const blines *b, double ya, double yb, double *lo, double *hi)
{
    double xl = -INFINITY, xr = INFINITY;
    for (uint32_t k = 0; k < b->nl; k++) {
        double p = bline_x(&b->l[k], ya), q = bline_x(&b->l[k], yb);
        p = p > -INFINITY ? p : -INFINITY;
        q = q > -INFINITY ? q : -INFINITY;
        double m = p < q ? p : q;
        xl = m > xl ? m : xl;
    }
    for (uint32_t k = 0; k < b->nu; k++) {
        double p = bline_x(&b->u[k], ya), q = bline_x(&b->u[k], yb);
        p = p < INFINITY ? p : INFINITY;
        q = q < INFINITY ? q : INFINITY;
        double m = p > q ? p : q;
        xr = m < xr ? m : xr;
    }
    for (uint32_t k = 0; k < b->nz; k++) {
        const bline *z = &b->z[k];
        if (z->c + z->cy * ya - z->bound < 0 && z->c + z->cy * yb - z->bound < 0)
            xr = -INFINITY;
    }
    *lo = xl;
    *hi = xr;
}

/* Is any bit of [i0, i1] set? */
static inline bool bits_any(const uint64_t *w, int32_t i0, int32_t i1)
{
    uint32_t a = (uint32_t)i0 >> 6, b = (uint32_t)i1 >> 6;
    uint64_t ma = ~0ull << (i0 & 63), mb = ~0ull >> (63 - (i1 & 63));
    if (a == b)
        return (w[a] & ma & mb) != 0;
    if (w[a] & ma)
        return true;
    for (uint32_t k = a + 1; k < b; k++)
        if (w[k])
            return true;
    return (w[b] & mb) != 0;
}

/* What the cells of one call share. */
typedef struct raster_ctx {
    const sl_cullmap_grid *map;
    const double *eye;
    const sl_shadow_edge *window;
    uint32_t lo, first, last;     /* window offset of w[0]; the chain's ends in w (facing the eye) */
    bool part, clip_low;
    double low;                   /* with clip_low: shadows below this hide nothing */
    double l;                     /* half the cell plus the margin */
    wedge *w;                     /* the window's wedges, made when first needed */
    bool *made;
} raster_ctx;

/* Wedge k of the window, made on first use. */
static inline const wedge *ctx_wedge(const raster_ctx *rc, uint32_t k)
{
    if (!rc->made[k]) {
        rc->w[k] = make_wedge(&rc->window[rc->lo + k], rc->eye, rc->l);
        rc->w[k].easy_floor = rc->w[k].bottom_easy ? float_up(rc->w[k].base) : INFINITY;
        rc->made[k] = true;
    }
    return &rc->w[k];
}

/* A cell inside the wedge and clear of its rays and seams (the fast part): only the bottom test and
 * the value v (the top plane at its centre). */
static inline uint64_t fast_cell(const raster_ctx *rc, const wedge *ws, float *zrow, const float *frow,
                                 const float *trow, uint32_t i, uint32_t j, double x, double y, double v)
{
    if (frow && !(frow[i] >= ws->easy_floor) && !bottom_ok(ws, frow[i], x, y))
        return 0;
    return raise_cell(rc->map, zrow, trow, i, j, cell_float(v));
}

/* From wedge k, across its seam ray on side dir (-1: ray a, into the previous wedges of the chain;
 * +1: ray b, into the next ones), to the first wedge that holds the cell inside its ray on that
 * side; *v takes the minimum of their top planes. False when one of them fails (the cell not wholly
 * behind its edge, or below its bottom plane; degenerate) or the chain (or the window) ends first. */
static bool seam_walk(const raster_ctx *rc, uint32_t k, int dir, double x, double y, const float *frow, float fl,
                      double *v)
{
    for (uint32_t q = k;;) {
        q = dir < 0 ? q - 1 : q + 1;
        const wedge *wq = ctx_wedge(rc, q);
        if (!wq->ok || lin_at(&wq->behind, x, y) < 0 || (frow && !bottom_ok(wq, fl, x, y)))
            return false;
        *v = dmin2(*v, lin_at(&wq->top, x, y));
        if (dir < 0 ? lin_at(&wq->ray_a, x, y) >= wq->eps_a : lin_at(&wq->ray_b, x, y) >= wq->eps_b)
            return true;
        if (q == (dir < 0 ? rc->first : rc->last))
            return false;
    }
}

/* Cell (i, j), centre (x, y), in the shadow of wedge k of the window: every test (behind the edge,
 * inside the rays or straddling one for a partial cover, the bottom, across seams the neighbouring
 * wedges of the chain). Valid for any cell: one outside the shadow is left alone. */
static uint64_t slow_cell(const raster_ctx *rc, uint32_t k, float *zrow, const float *frow, const float *trow,
                          uint32_t i, uint32_t j, double x, double y)
{
    const wedge *ws = &rc->w[k];
    const float fl = frow ? frow[i] : INFINITY;
    if (lin_at(&ws->behind, x, y) < 0)
        return 0;
    double v = lin_at(&ws->top, x, y);
    if (rc->clip_low && v < rc->low)
        return 0; /* the shadow is below anything here */
    const bool seam_a = k > rc->first, seam_b = k < rc->last;
    /* full coverage at a silhouette side needs the cell inside the ray */
    const double bound_a = seam_a ? -ws->eps_a : ws->eps_a, bound_b = seam_b ? -ws->eps_b : ws->eps_b;
    double da = lin_at(&ws->ray_a, x, y), db = lin_at(&ws->ray_b, x, y);
    if (da < bound_a || db < bound_b) {
        /* straddling a silhouette ray (wholly behind the edge): a partial cover, unless the cell
         * also reaches across a seam ray (then this shadow's part of it is not known: only the seam
         * rule could tell, which needs full coverage) */
        bool sa = da < ws->eps_a, sb = db < ws->eps_b;
        if (rc->part && da >= -ws->eps_a && db >= -ws->eps_b && !(sa && seam_a) && !(sb && seam_b) &&
            !(frow && !bottom_ok(ws, fl, x, y)) && v - 1e-4 > (double)zrow[i]) { /* only when it could raise it */
            const sl_shadow_edge *e = &rc->window[rc->lo + k];
            double pa_az = paz(e->ax - rc->eye[0], e->ay - rc->eye[1]);
            double pb_az = paz(e->bx - rc->eye[0], e->by - rc->eye[1]);
            return partial(rc->map, rc->eye, i, j, rc->l, pa_az, pb_az, sa, sb, v, zrow, trow);
        }
        return 0;
    }
    if (frow && !bottom_ok(ws, fl, x, y))
        return 0;
    if (!(v - 1e-4 > (double)zrow[i]))
        return 0; /* it would not raise the cell */
    /* the cell reaches across ray a into the previous wedges, or across ray b into the next ones */
    if (seam_a && da < ws->eps_a && !seam_walk(rc, k, -1, x, y, frow, fl, &v))
        return 0;
    if (seam_b && db < ws->eps_b && !seam_walk(rc, k, +1, x, y, frow, fl, &v))
        return 0;
    return raise_cell(rc->map, zrow, trow, i, j, cell_float(v));
}

/* Rows j0..j1 that the shadow of ws may touch: the clip's bounding rectangle cut by the wedge's
 * lines (the rays moved by span_a, span_b; above the useful minimum when clip_low), a row more on
 * each side. False when none. */
static bool wedge_rows(const sl_cullmap_grid *map, const wedge *ws, double span_a, double span_b,
                       const sl_cullmap_clip *clip, double l, bool clip_low, double low, uint32_t *j0, uint32_t *j1)
{
    const double cell = map->cell, x0 = map->min_x, y0 = map->min_y;
    double rect[4][2] = {{x0 + clip->i0 * cell, y0 + clip->j0 * cell},
                         {x0 + (clip->i1 + 1.0) * cell, y0 + clip->j0 * cell},
                         {x0 + (clip->i1 + 1.0) * cell, y0 + (clip->j1 + 1.0) * cell},
                         {x0 + clip->i0 * cell, y0 + (clip->j1 + 1.0) * cell}};
    double pa[16][2], pb[16][2];
    int m = clip_poly((const double(*)[2])rect, 4, &ws->behind, -l, pa);
    m = clip_poly((const double(*)[2])pa, m, &ws->ray_a, span_a - l, pb);
    m = clip_poly((const double(*)[2])pb, m, &ws->ray_b, span_b - l, pa);
    /* where the shadow is worth anything: above the map's lowest floor */
    if (clip_low && m >= 3) {
        m = clip_poly((const double(*)[2])pa, m, &ws->top, low - l * (fabs(ws->top.cx) + fabs(ws->top.cy)), pb);
        memcpy(pa, pb, sizeof(double) * 2 * (size_t)(m > 0 ? m : 0));
    }
    if (m < 3)
        return false;
    double ylo = INFINITY, yhi = -INFINITY;
    for (int i = 0; i < m; i++) {
        ylo = fmin(ylo, pa[i][1]);
        yhi = fmax(yhi, pa[i][1]);
    }
    double fj0 = fmax((double)clip->j0, floor((ylo - y0) / cell - 0.5) - 1);
    double fj1 = fmin((double)clip->j1, ceil((yhi - y0) / cell - 0.5) + 1);
    if (!(fj0 <= fj1))
        return false;
    *j0 = (uint32_t)fj0;
    *j1 = (uint32_t)fj1;
    return true;
}

uint64_t sl_cullmap_raster_wedge(sl_cullmap_grid *map, const double eye[3], const sl_shadow_edge *window, uint32_t count,
                                 uint32_t self, const sl_cullmap_clip *clip)
{
    if (!map || !window || !clip || self >= count || clip->j0 > clip->j1 || clip->j1 >= map->ny ||
        clip->i0 > clip->i1 || clip->i1 >= map->nx)
        return 0;
    const double l = 0.5 * map->cell + map->margin;
    /* the seam partners that can matter */
    uint32_t lo = self > SL_CULLMAP_MAX_SEAM ? self - SL_CULLMAP_MAX_SEAM : 0;
    uint32_t hi = count - 1 - self > SL_CULLMAP_MAX_SEAM ? self + SL_CULLMAP_MAX_SEAM : count - 1;
    /* the neighbours' functions are made when a seam cell first needs them */
    wedge w[2 * SL_CULLMAP_MAX_SEAM + 1];
    bool made[2 * SL_CULLMAP_MAX_SEAM + 1] = {false};
    const uint32_t s = self - lo, n = hi - lo + 1;
    raster_ctx rc = {map, eye, window, lo, 0, 0, map->part != NULL, map->useful_min > -INFINITY,
                     map->useful_min > -INFINITY ? (double)map->useful_min : 0.0, l, w, made};
    const wedge *ws = ctx_wedge(&rc, s);
    if (!ws->ok)
        return 0;
    /* a neighbour that does not face the eye (or is degenerate) ends the chain there */
    uint32_t first = s, last = s;
    while (first > 0 && faces(&window[lo + first - 1], eye))
        first--;
    while (last + 1 < n && faces(&window[lo + last + 1], eye))
        last++;
    rc.first = first;
    rc.last = last;
    const bool seam_a = s > first, seam_b = s < last;
    /* full coverage at a silhouette side needs the cell inside the ray; with partial coverage the
     * cells straddling it are visited too (span_*) */
    const double bound_a = seam_a ? -ws->eps_a : ws->eps_a, bound_b = seam_b ? -ws->eps_b : ws->eps_b;
    const double span_a = rc.part ? -ws->eps_a : bound_a, span_b = rc.part ? -ws->eps_b : bound_b;
    const bool clip_low = rc.clip_low;
    const double low = rc.low;
    uint32_t j0, j1;
    if (!wedge_rows(map, ws, span_a, span_b, clip, l, clip_low, low, &j0, &j1))
        return 0;
    const double cell = map->cell, x0 = map->min_x, y0 = map->min_y;

    /* the rows' cell ranges, a band of 2^block_shift rows at a time (one row at a time without
     * saturation); the band is skipped when the cells its part of the wedge can touch are all
     * saturated; then only the unsaturated cells of each row are visited (from the row bits, or
     * block by block skipping the saturated blocks) */
    uint64_t written = 0;
    const size_t nx = map->nx;
    const double inv_cell = 1.0 / cell;
    const uint32_t bs = map->top ? (map->block_shift > 6 ? 6 : map->block_shift) : 0;
    const uint32_t band = 1u << bs;
    const bool bits = map->top && map->row_bits && map->band_bits && map->band_count;
    /* the lines bounding the rows (behind the edge, between the rays, above the useful minimum) and
     * those bounding the part clear of the rays (the fast part: only the value is needed there) */
    blines sp, fl;
    memset(&sp, 0, sizeof sp);
    memset(&fl, 0, sizeof fl);
    blines_add(&sp, &ws->behind, 0.0);
    blines_add(&sp, &ws->ray_a, span_a);
    blines_add(&sp, &ws->ray_b, span_b);
    if (clip_low)
        blines_add(&sp, &ws->top, low);
    blines_add(&fl, &ws->ray_a, ws->eps_a);
    blines_add(&fl, &ws->ray_b, ws->eps_b);
    row_span rs[64];
    for (uint32_t jb = j0; jb <= j1;) {
        uint32_t jend = ((jb >> bs) + 1) << bs; /* first row of the next band */
        if (jend > j1 + 1)
            jend = j1 + 1;
        uint32_t nr = jend - jb;
        if (map->top && (bs > 0 || bits)) {
            /* the wedge's x-range over the band, from its lines at the band's ends (per line the
             * bound over the band is at an end: the looser end of each) */
            double ya = y0 + (jb + 0.5) * cell, yb = y0 + (jend - 0.5) * cell;
            double bl, br;
            blines_band(&sp, ya, yb, &bl, &br);
            int32_t cmin = INT32_MAX, cmax = -1;
            for (uint32_t j = jb; j < jend; j++) {
                int32_t a0 = clip->x0[j - clip->j0], a1 = clip->x1[j - clip->j0];
                cmin = a0 < cmin ? a0 : cmin;
                cmax = a1 > cmax ? a1 : cmax;
            }
            if (cmin < 0)
                cmin = 0;
            if (cmax >= (int32_t)nx)
                cmax = (int32_t)nx - 1;
            /* clamp before converting: the bounds may be infinite */
            if (bl < x0 + (cmin - 1.0) * cell)
                bl = x0 + (cmin - 1.0) * cell;
            if (br > x0 + (cmax + 2.0) * cell)
                br = x0 + (cmax + 2.0) * cell;
            double g0 = sl_cullmap_ffloor((bl - x0) * inv_cell - 1.5);
            double g1 = sl_cullmap_fceil((br - x0) * inv_cell + 0.5);
            g0 = g0 > (double)cmin ? g0 : (double)cmin;
            g1 = g1 < (double)cmax ? g1 : (double)cmax;
            bool any = false;
            if (g0 <= g1 && bl <= br) {
                size_t row = (size_t)(jb >> bs) * map->bnx;
                if (bits)
                    any = bits_any(map->band_bits + (size_t)(jb >> bs) * map->words, (int32_t)g0, (int32_t)g1);
                else {
                    const uint16_t *ub = map->unsat + row;
                    const float *bz = NULL, *bt = NULL; /* block_top is NULL without block_z */
                    if (map->block_z) {
                        bz = map->block_z + row;
                        bt = map->block_top + row;
                    }
                    for (int32_t bi = (int32_t)g0 >> bs; bi <= ((int32_t)g1 >> bs) && !any; bi++)
                        any = ub[bi] != 0 && !(bz && bz[bi] >= bt[bi]);
                }
            }
            if (!any) {
                jb = jend;
                continue;
            }
        }
        if (bits) {
            /* each row's range, then its unsaturated cells, each judged whole (slow_cell: with the
             * bits few cells are left to visit, and the range need not be exact, only a cell left
             * out loses occlusion) */
            for (uint32_t j = jb; j < jend; j++) {
                int32_t cx0 = clip->x0[j - clip->j0], cx1 = clip->x1[j - clip->j0];
                cx0 = cx0 < 0 ? 0 : cx0;
                cx1 = cx1 >= (int32_t)nx ? (int32_t)nx - 1 : cx1;
                if (cx0 > cx1)
                    continue;
                const double y = y0 + (j + 0.5) * cell;
                double xl = -INFINITY, xr = INFINITY;
                blines_narrow(&sp, y, &xl, &xr);
                /* in cell units, clamped to the clip (the bounds may be infinite) */
                double u0 = (xl - x0) * inv_cell - 0.5 - 1e-7, u1 = (xr - x0) * inv_cell - 0.5 + 1e-7;
                u0 = u0 > cx0 - 1.0 ? u0 : cx0 - 1.0;
                u1 = u1 < cx1 + 1.0 ? u1 : cx1 + 1.0;
                if (!(u0 <= u1))
                    continue;
                /* ceil and floor (the values are within the int32 range), without a branch */
                int32_t i0 = (int32_t)u0, i1 = (int32_t)u1;
                i0 += u0 > (double)i0;
                i1 -= u1 < (double)i1;
                i0 = i0 > cx0 ? i0 : cx0;
                i1 = i1 < cx1 ? i1 : cx1;
                if (i0 > i1)
                    continue;
                float *zrow = map->z + (size_t)j * nx;
                const float *frow = map->floor ? map->floor + (size_t)j * nx : NULL;
                const float *trow = map->top + (size_t)j * nx;
                const uint64_t *rb = map->row_bits + (size_t)j * map->words;
                const uint32_t wa = (uint32_t)i0 >> 6, wb = (uint32_t)i1 >> 6;
                for (uint32_t k = wa; k <= wb; k++) {
                    uint64_t bw = rb[k];
                    if (k == wa)
                        bw &= ~0ull << (i0 & 63);
                    if (k == wb)
                        bw &= ~0ull >> (63 - (i1 & 63));
                    while (bw) {
                        const uint32_t i = (k << 6) + (uint32_t)__builtin_ctzll(bw);
                        bw &= bw - 1;
                        written += slow_cell(&rc, s, zrow, frow, trow, i, j, x0 + (i + 0.5) * cell, y);
                    }
                }
            }
            jb = jend;
            continue;
        }
        int32_t rlo = INT32_MAX, rhi = -1;
        for (uint32_t r = 0; r < nr; r++) {
            row_span *q = &rs[r];
            q->i0 = 1, q->i1 = 0;
            uint32_t j = jb + r;
            int32_t cx0 = clip->x0[j - clip->j0], cx1 = clip->x1[j - clip->j0];
            if (cx0 < 0)
                cx0 = 0;
            if (cx1 >= (int32_t)nx)
                cx1 = (int32_t)nx - 1;
            if (cx0 > cx1)
                continue;
            double y = y0 + (j + 0.5) * cell;
            double xl = -INFINITY, xr = INFINITY;
            blines_narrow(&sp, y, &xl, &xr);
            if (!(xl <= xr))
                continue;
            /* centres x0 + (i + 0.5) cell inside [xl, xr] (up to rounding: those at its ends get every
             * test, and a cell dropped by rounding only loses occlusion); the cells well inside and
             * clear of the rays need only the value */
            if (xl < x0 + cx0 * cell - cell)
                xl = x0 + cx0 * cell - cell;
            if (xr > x0 + (cx1 + 2.0) * cell)
                xr = x0 + (cx1 + 2.0) * cell;
            if (!(xl <= xr))
                continue;
            double fi0 = sl_cullmap_fceil((xl - x0) * inv_cell - 0.5 - 1e-7);
            double fi1 = sl_cullmap_ffloor((xr - x0) * inv_cell - 0.5 + 1e-7);
            fi0 = fi0 > (double)cx0 ? fi0 : (double)cx0;
            fi1 = fi1 < (double)cx1 ? fi1 : (double)cx1;
            if (!(fi0 <= fi1))
                continue;
            q->i0 = (int32_t)fi0, q->i1 = (int32_t)fi1;
            double fxl = xl, fxr = xr;
            blines_narrow(&fl, y, &fxl, &fxr);
            q->f0 = q->i1 + 1, q->f1 = q->i1;
            if (fxl <= fxr) {
                double g0 = sl_cullmap_fceil((fxl - x0) * inv_cell - 0.5 + 1e-6);
                double g1 = sl_cullmap_ffloor((fxr - x0) * inv_cell - 0.5 - 1e-6);
                if (g0 <= g1 && g1 >= (double)q->i0 && g0 <= (double)q->i1) {
                    q->f0 = g0 < (double)q->i0 ? q->i0 : (int32_t)g0;
                    q->f1 = g1 > (double)q->i1 ? q->i1 : (int32_t)g1;
                }
            }
            q->y = y;
            q->vrow = ws->top.c + ws->top.cy * y;
            rlo = q->i0 < rlo ? q->i0 : rlo;
            rhi = q->i1 > rhi ? q->i1 : rhi;
        }
        {
            /* the band's blocks left to right, skipping the saturated ones */
            for (int32_t bi = rlo >> bs; bi <= (rhi >> bs) && rlo <= rhi; bi++) {
                if (map->top) {
                    size_t b = (size_t)(jb >> bs) * map->bnx + (uint32_t)bi;
                    if (map->unsat[b] == 0 || (map->block_z && map->block_z[b] >= map->block_top[b]))
                        continue; /* every cell of the block is hidden already */
                }
                int32_t c0 = bi << bs, c1 = c0 + (int32_t)band - 1;
                for (uint32_t r = 0; r < nr; r++) {
                    const row_span *q = &rs[r];
                    int32_t a0 = q->i0 > c0 ? q->i0 : c0, a1 = q->i1 < c1 ? q->i1 : c1;
                    const uint32_t j = jb + r;
                    float *zrow = map->z + (size_t)j * nx;
                    const float *frow = map->floor ? map->floor + (size_t)j * nx : NULL;
                    const float *trow = map->top ? map->top + (size_t)j * nx : NULL;
                    for (int32_t i = a0; i <= a1; i++) {
                        if (trow && zrow[i] >= trow[i])
                            continue;
                        const double x = x0 + (i + 0.5) * cell;
                        if (i >= q->f0 && i <= q->f1)
                            written += fast_cell(&rc, ws, zrow, frow, trow, (uint32_t)i, j, x, q->y,
                                                 q->vrow + ws->top.cx * x);
                        else
                            written += slow_cell(&rc, s, zrow, frow, trow, (uint32_t)i, j, x, q->y);
                    }
                }
            }
        }
        jb = jend;
    }
    return written;
}

/* Cell (i, j) is unsaturated: set its bits (from a state where they are clear). */
static void mark_unsaturated(const sl_cullmap_grid *map, uint32_t i, uint32_t j)
{
    const uint32_t bs = map->block_shift > 6 ? 6 : map->block_shift;
    map->row_bits[(size_t)j * map->words + (i >> 6)] |= 1ull << (i & 63);
    map->band_bits[(size_t)(j >> bs) * map->words + (i >> 6)] |= 1ull << (i & 63);
    map->band_count[(size_t)(j >> bs) * map->nx + i]++;
}

void sl_cullmap_clear(sl_cullmap_grid *map, const sl_cullmap_clip *clip)
{
    if (!map || !clip || clip->j0 > clip->j1 || clip->j1 >= map->ny)
        return;
    for (uint32_t j = clip->j0; j <= clip->j1; j++) {
        int32_t a = clip->x0[j - clip->j0], b = clip->x1[j - clip->j0];
        if (a < 0)
            a = 0;
        if (b >= (int32_t)map->nx)
            b = (int32_t)map->nx - 1;
        float *row = map->z + (size_t)j * map->nx;
        for (int32_t i = a; i <= b; i++)
            row[i] = -INFINITY;
        if (map->top) {
            const float *trow = map->top + (size_t)j * map->nx;
            uint16_t *brow = map->unsat + (size_t)(j >> map->block_shift) * map->bnx;
            for (int32_t i = a; i <= b; i++)
                brow[i >> map->block_shift] += trow[i] > -INFINITY;
            if (map->row_bits && map->band_bits && map->band_count)
                for (int32_t i = a; i <= b; i++)
                    if (trow[i] > -INFINITY)
                        mark_unsaturated(map, (uint32_t)i, j);
        }
    }
}

void sl_cullmap_merge_min(sl_cullmap_grid *dst, const sl_cullmap_grid *src, const sl_cullmap_clip *clip)
{
    if (!dst || !src || !clip || dst->nx != src->nx || dst->ny != src->ny || clip->j0 > clip->j1 ||
        clip->j1 >= dst->ny)
        return;
    for (uint32_t j = clip->j0; j <= clip->j1; j++) {
        int32_t a = clip->x0[j - clip->j0], b = clip->x1[j - clip->j0];
        if (a < 0)
            a = 0;
        if (b >= (int32_t)dst->nx)
            b = (int32_t)dst->nx - 1;
        float *d = dst->z + (size_t)j * dst->nx;
        const float *s = src->z + (size_t)j * src->nx;
        for (int32_t i = a; i <= b; i++)
            if (s[i] < d[i])
                d[i] = s[i];
    }
}

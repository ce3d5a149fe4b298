/* The scalar front end of the occlusion rasterizer and the reference setup: vertex transform,
 * rejection of bad input, homogeneous clipping (near plane, w > epsilon, x/y guard band), snapping
 * to 1/256 pixel and the exact edge and conservative depth-plane setup of sl_rt_tri
 * (raster_internal.h). The SIMD paths run batched copies of the front end and of the
 * depth-plane setup (raster_batch.h) that repeat these operations exactly, and clip through this
 * code; that, exact coverage and an identical float sequence in the kernels make every path's
 * buffer bit-identical. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#include <math.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* Outcode bits: outside one frustum plane (x<-w, y<-w, z<-w, x>w, y>w, z>w), then the reasons to
 * clip: beyond the x/y guard band, w below near_w (OC_NEAR also asks for clipping). */
enum {
    OC_LEFT = 1, OC_BOTTOM = 2, OC_NEAR = 4, OC_RIGHT = 8, OC_TOP = 16, OC_FAR = 32,
    OC_GX = 64, OC_GY = 128, OC_W = 256
};
#define OC_FRUSTUM 63
#define OC_CLIP (OC_NEAR | OC_W | OC_GX | OC_GY)
#define MAX_POLY 12

void sl_rt_view_init(sl_rt_view *v, uint32_t width, uint32_t height, float near_w, sl_raster_depth depth)
{
    v->half_w = 0.5f * (float)width;
    v->half_h = 0.5f * (float)height;
    /* pixel x = (x/w)*half_w + half_w stays in [-GUARD, width+GUARD] while |x/w| <= guard_x */
    v->guard_x = 1.0f + SL_RT_GUARD_PX / v->half_w;
    v->guard_y = 1.0f + SL_RT_GUARD_PX / v->half_h;
    v->near_w = near_w;
    v->depth = depth;
    v->width = (int32_t)width;
    v->height = (int32_t)height;
    v->pad_w = (int32_t)((width + SL_RT_TILE_W - 1) / SL_RT_TILE_W * SL_RT_TILE_W);
    v->pad_h = (int32_t)((height + SL_RT_TILE_H - 1) / SL_RT_TILE_H * SL_RT_TILE_H);
}

void sl_rt_transform(const float *m, const float *p, float out[4])
{
    for (int r = 0; r < 4; r++)
        out[r] = ((m[r] * p[0] + m[4 + r] * p[1]) + m[8 + r] * p[2]) + m[12 + r];
}

float sl_rt_depth_of(const sl_rt_view *v, const float c[4])
{
    float inv = 1.0f / c[3];
    return v->depth == SL_RASTER_DEPTH_INV_W ? inv : 0.5f - 0.5f * (c[2] * inv);
}

/* The snap below, on SSE registers where available. Identical IEEE operations either way:
 * hh - a*hh is computed as a*(-hh) + hh and 0.5 - 0.5*a as a*(-0.5) + 0.5, which are the same
 * values (negating a product or an addend is exact). */
bool sl_rt_snap(const sl_rt_view *v, const float c[4], int32_t *X, int32_t *Y, float *d)
{
    if (!(c[3] > 0.0f))
        return false;
#if defined(__SSE2__)
    __m128 cv = _mm_loadu_ps(c);
    __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), _mm_shuffle_ps(cv, cv, 0xFF));
    __m128 p = _mm_mul_ps(cv, inv);
    __m128 s = _mm_add_ps(_mm_mul_ps(p, _mm_setr_ps(v->half_w, -v->half_h, -0.5f, 0.0f)),
                          _mm_setr_ps(v->half_w, v->half_h, 0.5f, 0.0f));
    float dd = v->depth == SL_RASTER_DEPTH_INV_W ? _mm_cvtss_f32(inv) : _mm_cvtss_f32(_mm_shuffle_ps(s, s, 2));
    __m128 lim = _mm_set1_ps(SL_RT_SNAP_LIMIT);
    __m128 in = _mm_and_ps(_mm_cmple_ps(s, lim), _mm_cmpge_ps(s, _mm_sub_ps(_mm_setzero_ps(), lim)));
    if ((_mm_movemask_ps(in) & 3) != 3 || !isfinite(dd))
        return false;
    __m128i xy = _mm_cvtps_epi32(_mm_mul_ps(s, _mm_set1_ps((float)SL_RT_SUBPIX)));
    *X = _mm_cvtsi128_si32(xy);
    *Y = _mm_cvtsi128_si32(_mm_shuffle_epi32(xy, 1));
#else
    float inv = 1.0f / c[3];
    float sx = (c[0] * inv) * v->half_w + v->half_w;
    float sy = (c[1] * inv) * -v->half_h + v->half_h;
    float dd = v->depth == SL_RASTER_DEPTH_INV_W ? inv : (c[2] * inv) * -0.5f + 0.5f;
    if (!(sx >= -SL_RT_SNAP_LIMIT && sx <= SL_RT_SNAP_LIMIT && sy >= -SL_RT_SNAP_LIMIT && sy <= SL_RT_SNAP_LIMIT) ||
        !isfinite(dd))
        return false;
    *X = (int32_t)lrintf(sx * (float)SL_RT_SUBPIX);
    *Y = (int32_t)lrintf(sy * (float)SL_RT_SUBPIX);
#endif
    *d = dd;
    return true;
}

static inline int32_t clamp_i32(int32_t x, int32_t lo, int32_t hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* floor(a / 256) and ceil(a / 256); >> on a negative int is arithmetic with GCC and Clang */
static inline int32_t floor256(int32_t a) { return a >> 8; }
static inline int32_t ceil256(int32_t a) { return -((-a) >> 8); }

/* ceil/floor of an exact integer quotient num/den (|num| < 2^53), as int32 clamped to +-2^30 */
static inline int32_t ceil_q(double num, double den)
{
    double q = ceil(num / den);
    return q < -SL_RT_BIG ? -SL_RT_BIG : (q > SL_RT_BIG ? SL_RT_BIG : (int32_t)q);
}
static inline int32_t floor_q(double num, double den)
{
    double q = floor(num / den);
    return q < -SL_RT_BIG ? -SL_RT_BIG : (q > SL_RT_BIG ? SL_RT_BIG : (int32_t)q);
}

static inline int32_t min3i(int32_t a, int32_t b, int32_t c) { return sl_rt_mini(a, sl_rt_mini(b, c)); }
static inline int32_t max3i(int32_t a, int32_t b, int32_t c) { return sl_rt_maxi(a, sl_rt_maxi(b, c)); }

int sl_rt_prepare(const sl_rt_view *v, const int32_t Xi[3], const int32_t Yi[3], const float di[3], int mode,
                  bool query, sl_raster_backface backface, sl_rt_prim *p)
{
    int64_t area = ((int64_t)Xi[1] - Xi[0]) * ((int64_t)Yi[2] - Yi[0]) -
                   ((int64_t)Xi[2] - Xi[0]) * ((int64_t)Yi[1] - Yi[0]);
    if (area == 0)
        return -1;
    /* screen y points down: area > 0 here is clockwise in NDC */
    if ((backface == SL_RASTER_CULL_CW && area > 0) || (backface == SL_RASTER_CULL_CCW && area < 0))
        return 0;
    /* orient so that the inside is where every edge function is positive */
    int i1 = area > 0 ? 1 : 2, i2 = 3 - i1;
    p->area = (double)(area < 0 ? -area : area);
    p->X[0] = Xi[0], p->X[1] = Xi[i1], p->X[2] = Xi[i2];
    p->Y[0] = Yi[0], p->Y[1] = Yi[i1], p->Y[2] = Yi[i2];
    p->d[0] = di[0], p->d[1] = di[i1], p->d[2] = di[i2];

    int32_t xmin = min3i(Xi[0], Xi[1], Xi[2]), xmax = max3i(Xi[0], Xi[1], Xi[2]);
    int32_t ymin = min3i(Yi[0], Yi[1], Yi[2]), ymax = max3i(Yi[0], Yi[1], Yi[2]);
    int32_t c0, c1, r0, r1;
    if (mode == SL_RT_OUTER) {
        /* pixels whose closed square meets the box grown by the snapping error */
        c0 = ceil256(xmin - 1 - SL_RT_SUBPIX), c1 = floor256(xmax + 1) + 1;
        r0 = ceil256(ymin - 1 - SL_RT_SUBPIX), r1 = floor256(ymax + 1) + 1;
    } else {
        /* pixels whose centre lies in the box */
        c0 = ceil256(xmin - SL_RT_SUBPIX / 2), c1 = floor256(xmax - SL_RT_SUBPIX / 2) + 1;
        r0 = ceil256(ymin - SL_RT_SUBPIX / 2), r1 = floor256(ymax - SL_RT_SUBPIX / 2) + 1;
    }
    /* occluders may cover the padding of the last tiles; queries stop at the real screen */
    int32_t lim_w = query ? v->width : v->pad_w, lim_h = query ? v->height : v->pad_h;
    p->col0 = clamp_i32(c0, 0, lim_w), p->col1 = clamp_i32(c1, 0, lim_w);
    p->row0 = clamp_i32(r0, 0, lim_h), p->row1 = clamp_i32(r1, 0, lim_h);
    if (p->col0 >= p->col1 || p->row0 >= p->row1)
        return -2;
    return 1;
}

bool sl_rt_setup(const sl_rt_prim *p, int mode, bool query, sl_rt_tri *o)
{
    const int32_t *X = p->X, *Y = p->Y;
    const float *d = p->d;
    double area = p->area;
    int32_t col0 = p->col0, col1 = p->col1, row0 = p->row0, row1 = p->row1;
    int32_t xmin = min3i(X[0], X[1], X[2]), xmax = max3i(X[0], X[1], X[2]);
    int32_t ymin = min3i(Y[0], Y[1], Y[2]), ymax = max3i(Y[0], Y[1], Y[2]);

    /* edges: E(P) = dX*(Py - Ya) - dY*(Px - Xa) >= c at the pixel centre. Slot 3 of these
     * arrays is the dummy edge (no constraint, never active). Written without data-dependent
     * branches: which edges are left or right is random, and mispredictions cost more than
     * the arithmetic. */
    int64_t bbw = (int64_t)xmax - xmin, bbh = (int64_t)ymax - ymin;
    double en0[4], ens[4], eden[4];
    int32_t eja[4], ejb[4];
    unsigned lmask = 0, rmask = 0;
    for (int e = 0; e < 3; e++) {
        int a = e, b = e == 2 ? 0 : e + 1;
        int64_t dX = (int64_t)X[b] - X[a], dY = (int64_t)Y[b] - Y[a];
        int64_t c;
        if (mode == SL_RT_CENTER) {
            c = (dY < 0 || (dY == 0 && dX > 0)) ? 0 : 1; /* top-left edges own their centres */
            int32_t lo = sl_rt_mini(Y[a], Y[b]), hi = sl_rt_maxi(Y[a], Y[b]);
            eja[e] = ceil256(lo - SL_RT_SUBPIX / 2);
            ejb[e] = floor256(hi - SL_RT_SUBPIX / 2);
        } else {
            /* half a pixel diagonal plus the snapping error (docs/rasterizer.md) */
            int64_t m = 129 * (llabs(dX) + llabs(dY)) + bbw + bbh + 3;
            c = mode == SL_RT_INNER ? m : -m;
            eja[e] = -SL_RT_BIG;
            ejb[e] = SL_RT_BIG;
        }
        if (SL_UNLIKELY(dY == 0)) {
            /* dX*(256j + 128 - Ya) >= c limits the rows */
            double num = (double)(c - dX * (SL_RT_SUBPIX / 2 - Y[a])), dn = (double)(SL_RT_SUBPIX * dX);
            if (dX > 0)
                row0 = sl_rt_maxi(row0, ceil_q(num, dn));
            else
                row1 = sl_rt_mini(row1, floor_q(num, dn) + 1);
        }
        /* ceil(num / den) with den > 0: a left edge's numerator and denominator are negated */
        int64_t n0 = dX * (SL_RT_SUBPIX / 2 - Y[a]) - dY * (SL_RT_SUBPIX / 2 - X[a]) - c + (dY > 0 ? 1 : 0);
        int64_t sg = dY < 0 ? -1 : 1;
        en0[e] = (double)(sg * n0);
        ens[e] = (double)(sg * SL_RT_SUBPIX * dX);
        eden[e] = (double)(sg * SL_RT_SUBPIX * dY);
        lmask |= (unsigned)(dY < 0) << e;
        rmask |= (unsigned)(dY > 0) << e;
    }
    if (row0 >= row1)
        return false;
    en0[3] = -4503599627370496.0; /* -2^52: the threshold clamps to col0 */
    ens[3] = 0.0;
    eden[3] = 1.0;
    eja[3] = SL_RT_BIG;
    ejb[3] = -SL_RT_BIG;
    /* a triangle of positive area has a left and a right edge; the third, if any, goes to slot 2
     * with cap +BIG (a left bound) or -BIG (a right bound) */
    bool two_left = (lmask & (lmask - 1)) != 0, two_right = (rmask & (rmask - 1)) != 0;
    int sa = __builtin_ctz(lmask), sb = __builtin_ctz(rmask);
    int sc = two_left ? 31 - __builtin_clz(lmask) : (two_right ? 31 - __builtin_clz(rmask) : 3);
    o->cap = two_right ? -SL_RT_BIG : SL_RT_BIG;
    const int slot[3] = {sa, sb, sc};
    for (int k = 0; k < 3; k++) {
        o->num0[k] = en0[slot[k]];
        o->nstep[k] = ens[slot[k]];
        o->den[k] = eden[slot[k]];
        o->ja[k] = eja[slot[k]];
        o->jb[k] = ejb[slot[k]];
    }
    o->col0 = col0, o->col1 = col1, o->row0 = row0, o->row1 = row1;

    /* depth plane through the snapped vertices, in pixel units, relative to (col0, row0) */
    const double k = 1.0 / SL_RT_SUBPIX;
    double ex1 = (double)(X[1] - X[0]) * k, ey1 = (double)(Y[1] - Y[0]) * k;
    double ex2 = (double)(X[2] - X[0]) * k, ey2 = (double)(Y[2] - Y[0]) * k;
    double dd1 = (double)d[1] - (double)d[0], dd2 = (double)d[2] - (double)d[0];
    double inv_det = 65536.0 / area; /* det = ex1*ey2 - ex2*ey1 = area / 256^2, exactly */
    double a = (dd1 * ey2 - dd2 * ey1) * inv_det, b = (ex1 * dd2 - ex2 * dd1) * inv_det;
    double cref = (double)d[0] + a * ((double)col0 - X[0] * k) + b * ((double)row0 - Y[0] * k);
    float dmin = sl_rt_minf(sl_rt_minf(d[0], d[1]), d[2]);
    float dmax = sl_rt_maxf(sl_rt_maxf(d[0], d[1]), d[2]);
    o->zclamp = query ? dmax : dmin;
    o->x_ref = col0, o->y_ref = row0;
    /* a bound on every rounding of the float evaluation (< 2^-19 of the magnitudes involved),
     * plus a 1/256-pixel shift that covers evaluating at snapped rather than true positions */
    double fa = fabs(a), fb = fabs(b);
    double span = fabs(cref) + fa * (double)(col1 - col0 + 40) + fb * (double)(row1 - row0 + 40);
    double bias = span * 0x1p-19 + (fa + fb) * (1.0 / 256.0);
    if (span < 1e30 && fa < 1e30 && fb < 1e30) {
        float lo_x = mode == SL_RT_CENTER ? 0.5f : 0.0f, hi_x = mode == SL_RT_CENTER ? 7.5f : 8.0f;
        float lo_y = mode == SL_RT_CENTER ? 0.5f : 0.0f, hi_y = mode == SL_RT_CENTER ? 3.5f : 4.0f;
        /* occluders want the farthest (smallest) value over the sample area, queries the nearest */
        float ox = (a >= 0) != query ? lo_x : hi_x;
        float oy = (b >= 0) != query ? lo_y : hi_y;
        o->z0 = (float)(query ? cref + bias : cref - bias);
        o->zdx = (float)a;
        o->zdy = (float)b;
        /* off[k] = zdx * ((float)(8 * (k & 3)) + ox) + zdy * ((float)(4 * (k >> 2)) + oy) */
#if defined(__SSE2__)
        __m128 zx = _mm_mul_ps(_mm_set1_ps(o->zdx), _mm_add_ps(_mm_setr_ps(0, 8, 16, 24), _mm_set1_ps(ox)));
        __m128 zy0 = _mm_mul_ps(_mm_set1_ps(o->zdy), _mm_set1_ps(oy));
        __m128 zy1 = _mm_mul_ps(_mm_set1_ps(o->zdy), _mm_set1_ps(4.0f + oy));
        _mm_storeu_ps(o->off, _mm_add_ps(zx, zy0));
        _mm_storeu_ps(o->off + 4, _mm_add_ps(zx, zy1));
#else
        for (int s = 0; s < SL_RT_SUBTILES; s++)
            o->off[s] = o->zdx * ((float)(SL_RT_SUB_W * (s & 3)) + ox) + o->zdy * ((float)(SL_RT_SUB_H * (s >> 2)) + oy);
#endif
        if (isfinite(o->z0))
            return true;
    }
    /* a plane too steep to evaluate: the vertex bound alone is conservative */
    o->z0 = o->zclamp;
    o->zdx = o->zdy = 0.0f;
    for (int s = 0; s < SL_RT_SUBTILES; s++)
        o->off[s] = 0.0f;
    return true;
}

/* ---- clipping ---- */

typedef struct poly {
    float v[MAX_POLY][4];
    int n;
} poly;

static inline float plane_dist(int plane, const sl_rt_view *v, const float *c)
{
    switch (plane) {
    case 0: return c[2] + c[3];               /* near: z >= -w */
    case 1: return c[3] - v->near_w;          /* w >= near_w */
    case 2: return c[0] + v->guard_x * c[3];  /* guard band, x >= -gx*w */
    case 3: return v->guard_x * c[3] - c[0];
    case 4: return c[1] + v->guard_y * c[3];
    default: return v->guard_y * c[3] - c[1];
    }
}

/* Sutherland-Hodgman against the planes whose bits are set in need. */
static void clip_poly(const sl_rt_view *v, poly *p, unsigned need)
{
    static const unsigned plane_bit[6] = {OC_NEAR, OC_W | OC_NEAR, OC_GX, OC_GX, OC_GY, OC_GY};
    poly tmp;
    poly *src = p, *dst = &tmp;
    for (int pl = 0; pl < 6 && src->n > 0; pl++) {
        if (!(need & plane_bit[pl]))
            continue;
        dst->n = 0;
        for (int i = 0; i < src->n; i++) {
            const float *a = src->v[i], *b = src->v[(i + 1) % src->n];
            float da = plane_dist(pl, v, a), db = plane_dist(pl, v, b);
            if (da >= 0 && dst->n < MAX_POLY)
                memcpy(dst->v[dst->n++], a, sizeof(float) * 4);
            if ((da >= 0) != (db >= 0) && dst->n < MAX_POLY) {
                float t = da / (da - db);
                float *o = dst->v[dst->n++];
                for (int k = 0; k < 4; k++)
                    o[k] = a[k] + t * (b[k] - a[k]);
            }
        }
        poly *s = src;
        src = dst, dst = s;
    }
    if (src != p)
        *p = *src;
}

#define OC_BAD 512 /* a non-finite coordinate */

/* Vertex fetch for one batch: the matrix columns are loaded once. */
typedef struct fetcher {
    const sl_rt_view *v;
    const sl_rt_batch *b;
#if defined(__SSE2__)
    __m128 col[4], guard;
#endif
} fetcher;

static void fetcher_init(fetcher *f, const sl_rt_view *v, const sl_rt_batch *b)
{
    f->v = v;
    f->b = b;
#if defined(__SSE2__)
    for (int i = 0; i < 4; i++)
        f->col[i] = _mm_loadu_ps(b->m + 4 * i);
    f->guard = _mm_setr_ps(v->guard_x, v->guard_y, 0.0f, 0.0f);
#endif
}

/* Transform vertex i to clip space (as sl_rt_transform) and return its outcode (OC_BAD when a
 * coordinate is not finite). */
static inline unsigned fetch_vertex(const fetcher *f, uint32_t i, float c[4])
{
    float p[3];
    memcpy(p, (const char *)f->b->vertices + (size_t)i * f->b->stride, sizeof p);
#if defined(__SSE2__)
    __m128 r = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(f->col[0], _mm_set1_ps(p[0])),
                                                _mm_mul_ps(f->col[1], _mm_set1_ps(p[1]))),
                                     _mm_mul_ps(f->col[2], _mm_set1_ps(p[2]))),
                          f->col[3]);
    _mm_storeu_ps(c, r);
    __m128 z = _mm_sub_ps(r, r); /* NaN exactly where r is not finite */
    if (_mm_movemask_ps(_mm_cmpunord_ps(z, z)))
        return OC_BAD;
    const __m128 sign = _mm_set1_ps(-0.0f);
    __m128 w = _mm_shuffle_ps(r, r, 0xFF);
    unsigned o = (unsigned)_mm_movemask_ps(_mm_cmplt_ps(r, _mm_xor_ps(w, sign))) & 7u;
    o |= ((unsigned)_mm_movemask_ps(_mm_cmpgt_ps(r, w)) & 7u) << 3;
    o |= ((unsigned)_mm_movemask_ps(_mm_cmpgt_ps(_mm_andnot_ps(sign, r), _mm_mul_ps(f->guard, w))) & 3u) << 6;
    o |= c[3] < f->v->near_w ? OC_W : 0u;
    return o;
#else
    sl_rt_transform(f->b->m, p, c);
    float x = c[0], y = c[1], z = c[2], w = c[3];
    if (!isfinite(x) || !isfinite(y) || !isfinite(z) || !isfinite(w))
        return OC_BAD;
    unsigned o = 0;
    o |= x < -w ? OC_LEFT : 0u;
    o |= y < -w ? OC_BOTTOM : 0u;
    o |= z < -w ? OC_NEAR : 0u;
    o |= x > w ? OC_RIGHT : 0u;
    o |= y > w ? OC_TOP : 0u;
    o |= z > w ? OC_FAR : 0u;
    o |= fabsf(x) > f->v->guard_x * w ? OC_GX : 0u;
    o |= fabsf(y) > f->v->guard_y * w ? OC_GY : 0u;
    o |= w < f->v->near_w ? OC_W : 0u;
    return o;
#endif
}

static inline bool finite4(const float *c)
{
    return isfinite(c[0]) && isfinite(c[1]) && isfinite(c[2]) && isfinite(c[3]);
}

/* Read, transform and classify the three vertices of triangle t.
 * Returns 0 ok, 1 bad index, 2 non-finite, 3 outside the frustum; fills the codes' union. */
static inline int fetch_triangle(const fetcher *f, uint32_t t, float c[3][4], unsigned *ocor)
{
    const uint32_t *ix = f->b->indices + (size_t)t * 3;
    uint32_t i0 = ix[0], i1 = ix[1], i2 = ix[2], n = f->b->vertex_count;
    if (i0 >= n || i1 >= n || i2 >= n)
        return 1;
    unsigned o0 = fetch_vertex(f, i0, c[0]), o1 = fetch_vertex(f, i1, c[1]), o2 = fetch_vertex(f, i2, c[2]);
    if ((o0 | o1 | o2) & OC_BAD)
        return 2;
    if (o0 & o1 & o2 & OC_FRUSTUM)
        return 3;
    *ocor = o0 | o1 | o2;
    return 0;
}

/* Clip a triangle and snap the polygon. Returns the vertex count (0 when nothing is left) or -1
 * when a vertex cannot be snapped. */
static int clip_and_snap(const sl_rt_view *v, float c[3][4], unsigned need, int32_t *X, int32_t *Y, float *d)
{
    poly p;
    p.n = 3;
    memcpy(p.v, c, sizeof(float) * 12);
    clip_poly(v, &p, need);
    for (int i = 0; i < p.n; i++)
        if (!finite4(p.v[i]) || !sl_rt_snap(v, p.v[i], &X[i], &Y[i], &d[i]))
            return -1;
    return p.n;
}

uint32_t sl_rt_front_prims(const sl_rt_view *v, int mode, const sl_rt_batch *b, uint32_t *next, uint32_t last,
                           sl_rt_counters *cnt, sl_rt_prim *out, uint32_t cap)
{
    fetcher f;
    fetcher_init(&f, v, b);
    uint32_t n_out = 0, t = *next;
    for (; t < last && n_out + SL_RT_FAN_MAX <= cap; t++) {
        cnt->submitted++;
        float c[3][4];
        unsigned ocor = 0;
        int st = fetch_triangle(&f, t, c, &ocor);
        if (st) {
            if (st == 1)
                cnt->rejected_index++;
            else if (st == 2)
                cnt->rejected_nonfinite++;
            else
                cnt->culled_outside++;
            continue;
        }
        int32_t X[MAX_POLY], Y[MAX_POLY];
        float d[MAX_POLY];
        int n = 3;
        if (ocor & OC_CLIP) {
            cnt->clipped++;
            n = clip_and_snap(v, c, ocor & OC_CLIP, X, Y, d);
        } else {
            for (int i = 0; i < 3 && n == 3; i++)
                if (!sl_rt_snap(v, c[i], &X[i], &Y[i], &d[i]))
                    n = -1;
        }
        if (n < 0) {
            cnt->rejected_nonfinite++;
            continue;
        }
        if (n < 3) {
            cnt->culled_outside++;
            continue;
        }
        /* fan of the (convex) clipped polygon */
        for (int i = 1; i + 1 < n; i++) {
            int32_t tx[3] = {X[0], X[i], X[i + 1]}, ty[3] = {Y[0], Y[i], Y[i + 1]};
            float td[3] = {d[0], d[i], d[i + 1]};
            int r = sl_rt_prepare(v, tx, ty, td, mode, false, b->backface, &out[n_out]);
            if (r == 1) {
                cnt->rasterized++;
                n_out++;
            } else if (r == 0) {
                cnt->culled_backface++;
            } else if (r == -1) {
                cnt->degenerate++;
            } else {
                cnt->culled_outside++;
            }
        }
    }
    *next = t;
    return n_out;
}

void sl_rt_render_each(void (*raster)(const sl_rt_target *, const sl_rt_tri *, int32_t, int32_t, int32_t, int32_t),
                       const sl_rt_target *tg, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0, int32_t tx1,
                       int32_t ty0, int32_t ty1)
{
    for (uint32_t i = 0; i < n; i++) {
        sl_rt_tri t;
        if (!sl_rt_setup(&p[i], mode, false, &t))
            continue;
        int32_t a0 = sl_rt_maxi(tx0, t.col0 / SL_RT_TILE_W), a1 = sl_rt_mini(tx1, (t.col1 - 1) / SL_RT_TILE_W + 1);
        int32_t b0 = sl_rt_maxi(ty0, t.row0 / SL_RT_TILE_H), b1 = sl_rt_mini(ty1, (t.row1 - 1) / SL_RT_TILE_H + 1);
        if (a0 < a1 && b0 < b1)
            raster(tg, &t, a0, a1, b0, b1);
    }
}

/* A degenerate (zero-area after snapping) query triangle still marks pixels: test its box. */
static bool degenerate_visible(const sl_rt_view *v, const sl_rt_kernels *k, const sl_rt_target *t,
                               const int32_t X[3], const int32_t Y[3], const float d[3])
{
    int32_t xmin = min3i(X[0], X[1], X[2]), xmax = max3i(X[0], X[1], X[2]);
    int32_t ymin = min3i(Y[0], Y[1], Y[2]), ymax = max3i(Y[0], Y[1], Y[2]);
    int32_t x0 = clamp_i32(ceil256(xmin - 1 - SL_RT_SUBPIX), 0, v->width);
    int32_t x1 = clamp_i32(floor256(xmax + 1) + 1, 0, v->width);
    int32_t y0 = clamp_i32(ceil256(ymin - 1 - SL_RT_SUBPIX), 0, v->height);
    int32_t y1 = clamp_i32(floor256(ymax + 1) + 1, 0, v->height);
    if (x0 >= x1 || y0 >= y1)
        return false;
    float dn = sl_rt_maxf(sl_rt_maxf(d[0], d[1]), d[2]);
    return !sl_rt_rect_occluded(k, t, x0, y0, x1, y1, dn);
}

sl_raster_result sl_rt_query_batch(const sl_rt_view *v, const sl_rt_kernels *k, const sl_rt_target *t,
                                   const sl_rt_batch *b)
{
    bool in_view = false;
    fetcher f;
    fetcher_init(&f, v, b);
    for (uint32_t tr = 0; tr < b->triangle_count; tr++) {
        float c[3][4];
        unsigned ocor = 0;
        int st = fetch_triangle(&f, tr, c, &ocor);
        if (st == 3)
            continue;
        if (st)
            return SL_RASTER_VISIBLE; /* bad index or non-finite: nothing can be concluded */
        int32_t X[MAX_POLY], Y[MAX_POLY];
        float d[MAX_POLY];
        int n = 3;
        if (ocor & OC_CLIP) {
            n = clip_and_snap(v, c, ocor & OC_CLIP, X, Y, d);
        } else {
            for (int i = 0; i < 3 && n == 3; i++)
                if (!sl_rt_snap(v, c[i], &X[i], &Y[i], &d[i]))
                    n = -1;
        }
        if (n < 0)
            return SL_RASTER_VISIBLE;
        if (n < 3)
            continue;
        in_view = true;
        for (int i = 1; i + 1 < n; i++) {
            int32_t tx[3] = {X[0], X[i], X[i + 1]}, ty[3] = {Y[0], Y[i], Y[i + 1]};
            float td[3] = {d[0], d[i], d[i + 1]};
            sl_rt_prim prim;
            sl_rt_tri tri;
            int r = sl_rt_prepare(v, tx, ty, td, SL_RT_OUTER, true, b->backface, &prim);
            if (r == 1 && sl_rt_setup(&prim, SL_RT_OUTER, true, &tri) && k->query_tri(t, &tri))
                return SL_RASTER_VISIBLE;
            if (r == -1 && degenerate_visible(v, k, t, tx, ty, td))
                return SL_RASTER_VISIBLE;
        }
    }
    return in_view ? SL_RASTER_OCCLUDED : SL_RASTER_OUTSIDE;
}

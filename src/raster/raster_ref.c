/* The oracle's reference rasterizer (see raster_ref.h for the conventions).
 *
 * Half-space rasterization with exact integer edge functions (Pineda 1988; the top-left rule as in
 * Direct3D 10 / OpenGL), homogeneous clipping (Sutherland-Hodgman in clip space, Blinn & Newell
 * 1978). Exactness beats speed here: every choice that could make two threads, two triangles
 * sharing an edge, or two runs disagree is made in integer or in a fixed order.
 */
#include "raster_ref.h"

#include <math.h>

enum {
    OC_NEAR = 1 << 0,
    OC_FAR = 1 << 1,
    OC_XNEG = 1 << 2,
    OC_XPOS = 1 << 3,
    OC_YNEG = 1 << 4,
    OC_YPOS = 1 << 5,
    OC_PLANES = 6
};

/* Largest polygon a triangle becomes after clipping against the six planes (3 + one per plane). */
#define MAX_POLY 12

static inline int64_t floor_div(int64_t a, int64_t b) /* b > 0 */
{
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

static inline int64_t ceil_div(int64_t a, int64_t b) /* b > 0 */
{
    return -floor_div(-a, b);
}

/* Signed distance-like value of clip-space point c to clip plane p: inside when >= 0. */
static inline double plane_dist(const double *c, int p, double gx, double gy)
{
    switch (p) {
    case 0: return c[2] + c[3];       /* near: z >= -w */
    case 1: return c[3] - c[2];       /* far: z <= w */
    case 2: return c[0] + gx * c[3];  /* guard band left */
    case 3: return gx * c[3] - c[0];  /* guard band right */
    case 4: return c[1] + gy * c[3];  /* guard band bottom */
    default: return gy * c[3] - c[1]; /* guard band top */
    }
}

static inline uint8_t outcode(const double *c, double gx, double gy)
{
    /* the planes of plane_dist, spelled out; !(d >= 0) so that a NaN counts as outside */
    const double x = c[0], y = c[1], z = c[2], w = c[3];
    return (uint8_t)(!(z + w >= 0) * OC_NEAR | !(w - z >= 0) * OC_FAR | !(x + gx * w >= 0) * OC_XNEG |
                     !(gx * w - x >= 0) * OC_XPOS | !(y + gy * w >= 0) * OC_YNEG | !(gy * w - y >= 0) * OC_YPOS);
}

/* Round to the nearest integer, ties to even (what llrint does in the default rounding mode),
 * without a library call: adding 1.5 * 2^52 leaves the integer in the low mantissa bits. Exact
 * for |v| < 2^31, which the guard band guarantees. */
static inline int32_t round_i32(double v)
{
    double t = v + 6755399441055744.0;
    int64_t bits;
    memcpy(&bits, &t, sizeof bits);
    return (int32_t)bits;
}

/* A projected vertex: exact screen position (pixels, double), its snapped fixed-point position
 * and its reversed depth. */
typedef struct svert {
    double x, y, z;
    int32_t X, Y;
} svert;

/* Project a clip-space point to the screen; false when it is not in front of the eye. */
static inline bool project(const sl_refrast_target *t, const double *c, svert *v)
{
    double w = c[3];
    if (!(w > 0))
        return false;
    double inv = 1.0 / w;
    v->x = (c[0] * inv + 1.0) * 0.5 * (double)t->width;
    v->y = (1.0 - c[1] * inv) * 0.5 * (double)t->height;
    v->X = round_i32(v->x * SL_REFRAST_SUBPIXEL);
    v->Y = round_i32(v->y * SL_REFRAST_SUBPIXEL);
    double d = 0.5 * (1.0 - c[2] * inv);
    v->z = d < 0 ? 0 : d > 1 ? 1 : d;
    return true;
}

void sl_refrast_clear(const sl_refrast_target *t)
{
    size_t n = (size_t)t->width * t->height;
    for (size_t i = 0; i < n; i++) {
        t->ids[i] = SL_NONE;
        t->depth[i] = 0.0f;
    }
    if (t->overdraw)
        memset(t->overdraw, 0, n * sizeof(uint32_t));
}

void sl_refrast_merge(const sl_refrast_target *dst, const sl_refrast_target *src, uint32_t y0, uint32_t y1)
{
    size_t first = (size_t)y0 * dst->width, last = (size_t)y1 * dst->width;
    for (size_t i = first; i < last; i++) {
        float z = src->depth[i];
        uint32_t id = src->ids[i];
        if (z > dst->depth[i] || (z == dst->depth[i] && id < dst->ids[i])) {
            dst->depth[i] = z;
            dst->ids[i] = id;
        }
    }
    if (dst->overdraw && src->overdraw)
        for (size_t i = first; i < last; i++)
            dst->overdraw[i] += src->overdraw[i];
}

bool sl_refrast_box_visible(const double vp[16], const sl_aabb *box, uint32_t width, uint32_t height)
{
    if (sl_aabb_is_empty(box))
        return false;
    /* the true frustum planes (not the guard band) of the matrix, inside where clip x, y, z lie
     * within +-w (left, right, bottom, top, near, far), unit normals, through the one box
     * classifier with its plane slack: a box beyond one of them covers no pixel centre, since
     * centres lie strictly inside the side planes */
    sl_plane planes[6];
    for (int i = 0; i < 6; i++) {
        const int r = i < 4 ? i / 2 : 2; /* the clip row tested against w */
        const double s = i < 4 ? (i & 1 ? -1.0 : 1.0) : (i == 4 ? 1.0 : -1.0);
        double q[4];
        for (int c = 0; c < 4; c++)
            q[c] = vp[4 * c + 3] + s * vp[4 * c + r];
        double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (!(len > 0) || !isfinite(len))
            return true; /* a degenerate matrix: no plane to reject by */
        planes[i] = (sl_plane){(float)(q[0] / len), (float)(q[1] / len), (float)(q[2] / len), (float)(q[3] / len)};
    }
    float slack[6];
    sl_frustum_slacks(planes, slack);
    if (sl_frustum_classify_box(planes, slack, box, 0x3fu, false, NULL) < 0)
        return false;
    bool all_front = true;
    double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? box->max.x : box->min.x, (k & 2) ? box->max.y : box->min.y,
                       (k & 4) ? box->max.z : box->min.z};
        double c[4];
        for (int r = 0; r < 4; r++)
            c[r] = vp[r] * p[0] + vp[4 + r] * p[1] + vp[8 + r] * p[2] + vp[12 + r];
        if (c[3] > 0) {
            double sx = (c[0] / c[3] + 1.0) * 0.5 * (double)width, sy = (1.0 - c[1] / c[3]) * 0.5 * (double)height;
            xmin = fmin(xmin, sx), xmax = fmax(xmax, sx);
            ymin = fmin(ymin, sy), ymax = fmax(ymax, sy);
        } else {
            all_front = false;
        }
    }
    if (!all_front)
        return true; /* the box reaches behind the eye: its projection is unbounded */
    /* with every corner in front of the eye the box projects inside the hull of its projected
     * corners; a tenth of a pixel of margin covers rounding (snapping moves 1/512 pixel) */
    const double m = 0.1;
    return floor(xmax - 0.5 + m) >= ceil(xmin - 0.5 - m) && floor(ymax - 0.5 + m) >= ceil(ymin - 0.5 - m);
}

bool sl_refrast_scratch_reserve(const sl_allocator *a, sl_refrast_scratch *s, size_t n)
{
    if (n <= s->cap)
        return true;
    size_t cap = s->cap ? s->cap : 256;
    while (cap < n)
        cap *= 2;
    double *clip = sl_alloc(a, cap * 4 * sizeof(double));
    struct svert *screen = sl_alloc(a, cap * sizeof(struct svert));
    uint8_t *code = sl_alloc(a, cap);
    if (!clip || !screen || !code) {
        sl_free(a, clip, cap * 4 * sizeof(double));
        sl_free(a, screen, cap * sizeof(struct svert));
        sl_free(a, code, cap);
        return false;
    }
    sl_refrast_scratch_free(a, s);
    s->clip = clip;
    s->screen = screen;
    s->code = code;
    s->cap = cap;
    return true;
}

void sl_refrast_scratch_free(const sl_allocator *a, sl_refrast_scratch *s)
{
    sl_free(a, s->clip, s->cap * 4 * sizeof(double));
    sl_free(a, s->screen, s->cap * sizeof(struct svert));
    sl_free(a, s->code, s->cap);
    s->clip = NULL;
    s->screen = NULL;
    s->code = NULL;
    s->cap = 0;
}

/* One edge a->b of a triangle with positive area: E(p) = A (px - ax) + B (py - ay) + bias >= 0
 * inside. bias is 0 on top and left edges (a centre exactly on them is covered) and -1 on the
 * others: with integer E, "E - 1 >= 0" is "E > 0". */
typedef struct edge {
    int64_t A, B, ax, ay, bias;
} edge;

static inline edge edge_setup(int32_t ax, int32_t ay, int32_t bx, int32_t by)
{
    edge e;
    int64_t dx = (int64_t)bx - ax, dy = (int64_t)by - ay;
    e.A = -dy;
    e.B = dx;
    e.ax = ax;
    e.ay = ay;
    /* y grows down and the interior is on the left of a->b seen on screen, i.e. E >= 0: an edge
     * going up is a left edge, a horizontal edge going right is a top edge */
    bool top_left = dy < 0 || (dy == 0 && dx > 0);
    e.bias = top_left ? 0 : -1;
    return e;
}

/* Narrow [*lo, *hi] to the columns x whose centre satisfies edge e in the row whose centre is py. */
static inline void edge_span(const edge *e, int64_t py, int64_t *lo, int64_t *hi)
{
    /* E(x) = K + S x with x the column, centre px = 256 x + 128 */
    int64_t K = e->A * ((int64_t)(SL_REFRAST_SUBPIXEL / 2) - e->ax) + e->B * (py - e->ay) + e->bias;
    int64_t S = e->A * SL_REFRAST_SUBPIXEL;
    if (S > 0) {
        int64_t x = ceil_div(-K, S);
        if (x > *lo)
            *lo = x;
    } else if (S < 0) {
        int64_t x = floor_div(K, -S);
        if (x < *hi)
            *hi = x;
    } else if (K < 0) {
        *hi = *lo - 1;
    }
}

/* Depth plane z = zbase + dzdx x + dzdy y through three (x, y, z) points; false when they are
 * collinear (or the result is not finite). */
static inline bool depth_plane(double x0, double y0, double z0, double x1, double y1, double z1, double x2, double y2,
                               double z2, double *dzdx, double *dzdy, double *zbase)
{
    double den = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
    double a = ((z1 - z0) * (y2 - y0) - (z2 - z0) * (y1 - y0)) / den;
    double b = ((z2 - z0) * (x1 - x0) - (z1 - z0) * (x2 - x0)) / den;
    double c = z0 - a * x0 - b * y0;
    if (!(den != 0) || !isfinite(a) || !isfinite(b) || !isfinite(c))
        return false;
    *dzdx = a, *dzdy = b, *zbase = c;
    return true;
}

/* Counting mode (sl_refrast_mesh_count); NULL when drawing as the oracle does. */
typedef struct count_ctx {
    bool test_only;
    uint64_t passed;
} count_ctx;

/* One row's span [lo, hi] in counting mode: the same depths as the drawing loop below, each
 * fragment at least as near as the stored depth counted, and stored unless test_only. Kept apart
 * so the oracle's loop is unchanged. */
static void count_span(uint32_t *ids, float *depth, int64_t lo, int64_t hi, double zrow, double dzdx, double zlo,
                       double zhi, uint32_t id, count_ctx *cc)
{
    const bool test_only = cc->test_only;
    uint64_t n = 0;
    for (int64_t x = lo; x <= hi; x++) {
        double z = zrow + dzdx * ((double)x + 0.5);
        z = z < zlo ? zlo : z > zhi ? zhi : z;
        float zf = (float)z;
        if (zf >= depth[x]) {
            n++;
            if (!test_only && (zf > depth[x] || id < ids[x])) {
                depth[x] = zf;
                ids[x] = id;
            }
        }
    }
    cc->passed += n;
}

/* Draw one triangle into the target's rows: coverage from the snapped positions, depth from the
 * exact ones (so snapping moves edges by at most 1/512 pixel but never tilts the depth). */
static void draw_triangle(const sl_refrast_target *t, const svert *v0, const svert *v1, const svert *v2, uint32_t id,
                          sl_refrast_cull cull, count_ctx *cc)
{
    int32_t X0 = v0->X, Y0 = v0->Y, X1 = v1->X, Y1 = v1->Y, X2 = v2->X, Y2 = v2->Y;
    int64_t area = ((int64_t)X1 - X0) * ((int64_t)Y2 - Y0) - ((int64_t)Y1 - Y0) * ((int64_t)X2 - X0);
    if (area == 0)
        return;
    /* y down flips the orientation: counter-clockwise in NDC (front) has a negative area here */
    if (area < 0) {
        if (cull == SL_REFRAST_CULL_FRONT)
            return;
        const svert *tmp = v1;
        v1 = v2, v2 = tmp;
        X1 = v1->X, Y1 = v1->Y, X2 = v2->X, Y2 = v2->Y;
    } else if (cull == SL_REFRAST_CULL_BACK) {
        return;
    }

    /* columns and rows whose centre k*256+128 lies in the snapped bounding box */
    const int64_t H = SL_REFRAST_SUBPIXEL / 2, S = SL_REFRAST_SUBPIXEL;
    int64_t minx = SL_MIN(X0, SL_MIN(X1, X2)), maxx = SL_MAX(X0, SL_MAX(X1, X2));
    int64_t miny = SL_MIN(Y0, SL_MIN(Y1, Y2)), maxy = SL_MAX(Y0, SL_MAX(Y1, Y2));
    int64_t cx0 = SL_MAX(ceil_div(minx - H, S), 0), cx1 = SL_MIN(floor_div(maxx - H, S), (int64_t)t->width - 1);
    int64_t cy0 = SL_MAX(ceil_div(miny - H, S), 0), cy1 = SL_MIN(floor_div(maxy - H, S), (int64_t)t->height - 1);
    if (cx0 > cx1 || cy0 > cy1)
        return;

    edge e0 = edge_setup(X0, Y0, X1, Y1), e1 = edge_setup(X1, Y1, X2, Y2), e2 = edge_setup(X2, Y2, X0, Y0);

    /* reversed depth is affine in screen space: the plane through the exact vertices, or through
     * the snapped ones for a sliver whose exact positions are collinear */
    double dzdx, dzdy, zbase;
    if (!depth_plane(v0->x, v0->y, v0->z, v1->x, v1->y, v1->z, v2->x, v2->y, v2->z, &dzdx, &dzdy, &zbase) &&
        !depth_plane(X0 / (double)S, Y0 / (double)S, v0->z, X1 / (double)S, Y1 / (double)S, v1->z, X2 / (double)S,
                     Y2 / (double)S, v2->z, &dzdx, &dzdy, &zbase)) {
        dzdx = dzdy = 0;
        zbase = (v0->z + v1->z + v2->z) / 3;
    }
    double zlo = fmin(v0->z, fmin(v1->z, v2->z)), zhi = fmax(v0->z, fmax(v1->z, v2->z));

    for (int64_t y = cy0; y <= cy1; y++) {
        int64_t py = y * S + H;
        int64_t lo = cx0, hi = cx1;
        edge_span(&e0, py, &lo, &hi);
        edge_span(&e1, py, &lo, &hi);
        edge_span(&e2, py, &lo, &hi);
        if (lo > hi)
            continue;
        double zrow = zbase + dzdy * ((double)y + 0.5);
        size_t row = (size_t)y * t->width;
        uint32_t *ids = t->ids + row;
        float *depth = t->depth + row;
        if (t->overdraw)
            for (int64_t x = lo; x <= hi; x++)
                t->overdraw[row + (size_t)x]++;
        if (cc) {
            count_span(ids, depth, lo, hi, zrow, dzdx, zlo, zhi, id, cc);
            continue;
        }
        for (int64_t x = lo; x <= hi; x++) {
            double z = zrow + dzdx * ((double)x + 0.5);
            z = z < zlo ? zlo : z > zhi ? zhi : z;
            float zf = (float)z;
            /* nearer wins; equally near goes to the lower id (see sl_refrast_merge) */
            if (zf > depth[x] || (zf == depth[x] && id < ids[x])) {
                depth[x] = zf;
                ids[x] = id;
            }
        }
    }
}

/* Clip polygon `in` (n vertices, 4 doubles each) against plane p into `out`; returns the new count.
 * An intersection is always interpolated from the inside vertex towards the outside one, so the
 * two triangles sharing an edge compute bit-identical points on it. */
static int clip_polygon(const double (*in)[4], int n, double (*out)[4], int p, double gx, double gy)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        const double *a = in[i], *b = in[(i + 1) % n];
        double da = plane_dist(a, p, gx, gy), db = plane_dist(b, p, gx, gy);
        bool ain = da >= 0, bin = db >= 0;
        if (ain)
            memcpy(out[m++], a, sizeof(double) * 4);
        if (ain != bin) {
            const double *u = ain ? a : b, *v = ain ? b : a;
            double du = ain ? da : db, dv = ain ? db : da;
            double s = du / (du - dv);
            for (int k = 0; k < 4; k++)
                out[m][k] = u[k] + s * (v[k] - u[k]);
            m++;
        }
    }
    return m;
}

/* Clip a triangle that straddles some planes (code = union of its vertex outcodes), then draw
 * the resulting convex polygon as a fan. */
static void draw_clipped(const sl_refrast_target *t, const double *c0, const double *c1, const double *c2, uint8_t code,
                         uint32_t id, sl_refrast_cull cull, count_ctx *cc)
{
    double buf[2][MAX_POLY][4];
    int n = 3, cur = 0;
    memcpy(buf[0][0], c0, sizeof(double) * 4);
    memcpy(buf[0][1], c1, sizeof(double) * 4);
    memcpy(buf[0][2], c2, sizeof(double) * 4);
    for (int p = 0; p < OC_PLANES && n >= 3; p++) {
        if (!(code & (1u << p)))
            continue;
        n = clip_polygon((const double(*)[4])buf[cur], n, buf[cur ^ 1], p, t->guard_x, t->guard_y);
        cur ^= 1;
    }
    if (n < 3)
        return;
    svert v[MAX_POLY];
    for (int i = 0; i < n; i++)
        if (!project(t, buf[cur][i], &v[i]))
            return;
    for (int i = 1; i + 1 < n; i++)
        draw_triangle(t, &v[0], &v[i], &v[i + 1], id, cull, cc);
}

static void mesh(const sl_refrast_target *t, sl_refrast_scratch *s, const double m[16], const float *positions,
                    uint32_t vertex_count, const uint32_t *indices, uint32_t triangle_count, uint32_t id,
                    sl_refrast_cull cull, count_ctx *count)
{
    /* transform every vertex once; snap the ones that need no clipping */
    for (uint32_t v = 0; v < vertex_count; v++) {
        const double px = positions[3 * v], py = positions[3 * v + 1], pz = positions[3 * v + 2];
        double *c = s->clip + 4 * (size_t)v;
        for (int r = 0; r < 4; r++)
            c[r] = m[r] * px + m[4 + r] * py + m[8 + r] * pz + m[12 + r];
        uint8_t code = outcode(c, t->guard_x, t->guard_y);
        if (code == 0 && !project(t, c, &s->screen[v]))
            code = OC_NEAR;
        s->code[v] = code;
    }
    for (uint32_t i = 0; i < triangle_count; i++) {
        uint32_t a = indices[3 * i], b = indices[3 * i + 1], c = indices[3 * i + 2];
        uint8_t ca = s->code[a], cb = s->code[b], cc = s->code[c];
        if (ca & cb & cc)
            continue; /* all three outside one plane */
        if ((ca | cb | cc) == 0)
            draw_triangle(t, &s->screen[a], &s->screen[b], &s->screen[c], id, cull, count);
        else
            draw_clipped(t, s->clip + 4 * (size_t)a, s->clip + 4 * (size_t)b, s->clip + 4 * (size_t)c, ca | cb | cc,
                         id, cull, count);
    }
}

void sl_refrast_mesh(const sl_refrast_target *t, sl_refrast_scratch *s, const double m[16], const float *positions,
                    uint32_t vertex_count, const uint32_t *indices, uint32_t triangle_count, uint32_t id,
                    sl_refrast_cull cull)
{
    mesh(t, s, m, positions, vertex_count, indices, triangle_count, id, cull, NULL);
}

uint64_t sl_refrast_mesh_count(const sl_refrast_target *t, sl_refrast_scratch *s, const double m[16],
                               const float *positions, uint32_t vertex_count, const uint32_t *indices,
                               uint32_t triangle_count, uint32_t id, sl_refrast_cull cull, bool test_only)
{
    count_ctx counted = {test_only, 0};
    mesh(t, s, m, positions, vertex_count, indices, triangle_count, id, cull, &counted);
    return counted.passed;
}

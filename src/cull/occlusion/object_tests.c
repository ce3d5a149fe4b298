/* Hidden-object tests by an object's own triangles (pixel-centre sampled and outward-conservative)
 * and by the pixel rows of a box's silhouette, over several layers and the exact layer
 * (object_tests.h). */
#include "object_tests.h"

#include "core/polygon.h"
#include "project.h"

#include <math.h>

/* Vertices projected at most once per sampled test, on first use (props have a few dozen; larger
 * meshes project per index). */
#define SAMPLED_VERTEX_CACHE 256


/* One sampled test (sl_occ_test_object_sampled): the layers, the rectangle, and per pixel of it
 * the nearest depth already proven hidden (-infinity: none). */
typedef struct sampled_test {
    sl_occ_raster *const *layers;
    uint32_t layer_count;
    sl_occ_exact *exact;
    /* the current triangle's oracle depth bound, computed when first needed (rd < 0: not yet) */
    double rd, mex[16];
    const float *tri[3];
    int32_t x0, y0, w, h;
    float *proven;
} sampled_test;

/* Is every pixel of [x0, x1) x [y0, y1) hidden at depth d in one layer? The rasterizer's rectangle
 * test is monotone in the pixel set (a subtile that hides a set of pixels hides each subset), so a
 * rectangle hidden in a layer proves each of its pixels hidden there: the per-pixel answers below
 * are unchanged, only fewer queries are made. */
static bool rect_hidden(sampled_test *t, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d)
{
    for (uint32_t l = 0; l < t->layer_count; l++)
        if (t->layers[l]->occluders_rendered &&
            sl_occ_raster_test(t->layers[l], x0, y0, x1, y1, d) != SL_RASTER_VISIBLE)
            return true;
    return false;
}

/* Is pixel (x, y) hidden at depth d (oracle depth rd) in some layer or in the exact layer?
 * Remembers the layers' answers (the exact layer's are in the oracle's depth order, which d does
 * not follow exactly). */
static bool sample_hidden(sampled_test *t, int32_t x, int32_t y, float d)
{
    float *p = t->proven + (size_t)(y - t->y0) * (size_t)t->w + (size_t)(x - t->x0);
    if (d <= *p)
        return true; /* hidden at a nearer depth already */
    if (t->exact && t->exact->drawn) {
        if (t->rd < 0.0) {
            /* the triangle's largest vertex depth as the oracle computes it (its fragments'
             * depths are clamped to the vertices' range) */
            double best = 0.0;
            for (int j = 0; j < 3; j++) {
                const float *q = t->tri[j];
                const double *mx = t->mex;
                double cl[4];
                for (int row = 0; row < 4; row++)
                    cl[row] = mx[row] * q[0] + mx[4 + row] * q[1] + mx[8 + row] * q[2] + mx[12 + row];
                double od = cl[3] > 0.0 ? oracle_depth(cl) : INFINITY;
                best = od > best ? od : best;
            }
            t->rd = best;
        }
        if (sl_occ_exact_hides(t->exact, x, y, t->rd))
            return true;
    }
    if (!rect_hidden(t, x, y, x + 1, y + 1, d))
        return false;
    *p = d;
    return true;
}

/* Test the pixel centres of the rectangle that lie within SL_OCC_MIN_INSET_PX of triangle (a, b,
 * c) (screen positions) at depth d; false at the first one not hidden. The margin covers the
 * oracle's 1/256-pixel vertex snapping (a snapped triangle lies within half a snapping step of the
 * exact one) and the rounding of this projection many times over; a triangle whose area is too
 * small for stable edge functions tests every centre of its grown bounding box. */
static bool sample_triangle(sampled_test *t, const double *a, const double *b, const double *c, float d)
{
    const double eps = SL_OCC_MIN_INSET_PX;
    double lx = a[0] < b[0] ? a[0] : b[0], hx = a[0] < b[0] ? b[0] : a[0];
    double ly = a[1] < b[1] ? a[1] : b[1], hy = a[1] < b[1] ? b[1] : a[1];
    lx = c[0] < lx ? c[0] : lx;
    hx = c[0] > hx ? c[0] : hx;
    ly = c[1] < ly ? c[1] : ly;
    hy = c[1] > hy ? c[1] : hy;
    /* the centres px + 0.5 in [lx - eps, hx + eps], clamped to the rectangle */
    double fx0 = ceil(lx - eps - 0.5), fx1 = floor(hx + eps - 0.5), fy0 = ceil(ly - eps - 0.5),
           fy1 = floor(hy + eps - 0.5);
    fx0 = fx0 > (double)t->x0 ? fx0 : (double)t->x0;
    fy0 = fy0 > (double)t->y0 ? fy0 : (double)t->y0;
    fx1 = fx1 < (double)(t->x0 + t->w - 1) ? fx1 : (double)(t->x0 + t->w - 1);
    fy1 = fy1 < (double)(t->y0 + t->h - 1) ? fy1 : (double)(t->y0 + t->h - 1);
    if (!(fx0 <= fx1) || !(fy0 <= fy1))
        return true;
    double area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    const double *v[3] = {a, b, c};
    double ex[3] = {0, 0, 0}, ey[3] = {0, 0, 0}, lim[3] = {0, 0, 0};
    bool thin = !(fabs(area2) > 1e-6);
    double sgn = area2 < 0 ? -1.0 : 1.0;
    for (int i = 0; i < 3 && !thin; i++) {
        const double *p = v[i], *q = v[(i + 1) % 3];
        ex[i] = sgn * (q[0] - p[0]);
        ey[i] = sgn * (q[1] - p[1]);
        /* inside or within eps: cross(e, s - p) >= -eps |e| (edges counter-clockwise) */
        lim[i] = -eps * sqrt(ex[i] * ex[i] + ey[i] * ey[i]) + ex[i] * p[1] - ey[i] * p[0];
    }
    /* one query for the centres' bounding rectangle, then one per row's span of centres inside
     * (an interval: the grown triangle is convex), then pixel by pixel where those cannot tell */
    int32_t px0 = (int32_t)fx0, px1 = (int32_t)fx1, py0 = (int32_t)fy0, py1 = (int32_t)fy1;
    if ((px1 > px0 || py1 > py0) && rect_hidden(t, px0, py0, px1 + 1, py1 + 1, d))
        return true;
    for (int32_t y = py0; y <= py1; y++) {
        double sy = y + 0.5;
        int32_t lo = px1 + 1, hi = px0 - 1;
        for (int32_t x = px0; x <= px1; x++) {
            double sx = x + 0.5;
            if (thin || (ex[0] * sy - ey[0] * sx >= lim[0] && ex[1] * sy - ey[1] * sx >= lim[1] &&
                         ex[2] * sy - ey[2] * sx >= lim[2])) {
                lo = x < lo ? x : lo;
                hi = x;
            }
        }
        if (hi > lo && py1 > py0 && rect_hidden(t, lo, y, hi + 1, y + 1, d))
            continue;
        for (int32_t x = lo; x <= hi; x++)
            if (!sample_hidden(t, x, y, d))
                return false;
    }
    return true;
}

sl_raster_result sl_occ_test_object_sampled(sl_occ_raster *const *layers, uint32_t layer_count,
                                            struct sl_occ_exact *exact, sl_scene scene, const sl_occ_view *v,
                                            uint32_t object, const sl_occ_rect *rect)
{
    int32_t w = rect->x1 - rect->x0, h = rect->y1 - rect->y0;
    if (w <= 0 || h <= 0 || (int64_t)w * h > SL_OCC_SAMPLED_MAX_PX || layer_count == 0)
        return SL_RASTER_VISIBLE;
    object_mesh om = get_object_mesh(scene, object);
    const sl_mesh_rec *mr = om.mr;
    const float *pos = om.pos;
    const uint32_t *idx = om.idx;
    double m[16];
    mul_affine_d(&v->vp, &om.xf, m);
    float proven[SL_OCC_SAMPLED_MAX_PX];
    for (int32_t i = 0; i < w * h; i++)
        proven[i] = -INFINITY;
    sampled_test t = {.layers = layers, .layer_count = layer_count, .exact = exact, .rd = -1.0,
                      .x0 = rect->x0, .y0 = rect->y0, .w = w, .h = h, .proven = proven};
    if (exact && exact->drawn)
        sl_refrast_compose(exact->vp, &om.xf, t.mex); /* the oracle's object-to-clip matrix */
    sl_occ_screen_vertex cache[SAMPLED_VERTEX_CACHE];
    bool have[SAMPLED_VERTEX_CACHE];
    bool cached = mr->vertex_count <= SAMPLED_VERTEX_CACHE;
    if (cached)
        memset(have, 0, mr->vertex_count * sizeof have[0]);
    layers[0]->queries++;
    for (uint32_t k = 0; k < mr->triangle_count; k++) {
        sl_occ_screen_vertex own[3];
        const sl_occ_screen_vertex *tv[3]; /* pointers: no copies of the cached vertices */
        for (int j = 0; j < 3; j++) {
            uint32_t vi = idx[3 * k + (uint32_t)j];
            if (vi >= mr->vertex_count)
                return SL_RASTER_VISIBLE;
            if (!cached) {
                own[j] = project_vertex(v, m, pos + 3 * (size_t)vi);
                tv[j] = &own[j];
            } else {
                if (!have[vi]) {
                    cache[vi] = project_vertex(v, m, pos + 3 * (size_t)vi);
                    have[vi] = true;
                }
                tv[j] = &cache[vi];
            }
            if (!tv[j]->ok)
                return SL_RASTER_VISIBLE;
        }
        /* the triangle's nearest depth, nudged nearer like a box's nearest corner */
        float dmax = sl_occ_maxf(tv[0]->d, sl_occ_maxf(tv[1]->d, tv[2]->d));
        dmax += fabsf(dmax) * SL_MARGIN_REL_F;
        t.rd = -1.0;
        for (int j = 0; j < 3; j++)
            t.tri[j] = pos + 3 * (size_t)idx[3 * k + (uint32_t)j];
        const double a[2] = {tv[0]->x, tv[0]->y}, b[2] = {tv[1]->x, tv[1]->y}, c[2] = {tv[2]->x, tv[2]->y};
        if (!sample_triangle(&t, a, b, c, dmax))
            return SL_RASTER_VISIBLE;
    }
    return SL_RASTER_OCCLUDED;
}


bool sl_occ_box_rows_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact,
                            const sl_occ_view *v, const sl_aabb *box, const sl_occ_rect *r, uint32_t max_rows)
{
    /* the corners of the box grown by 2^-20 of its coordinates (object boxes are computed in
     * float, the oracle places vertices in double), projected in double with the oracle's matrix
     * (a float projection of world coordinates errs by up to a tenth of a pixel near the eye) */
    double xy[16];
    const double W = (double)v->width, H = (double)v->height;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? grow_coord(box->max.x, 1) : grow_coord(box->min.x, -1),
                       (k & 2) ? grow_coord(box->max.y, 1) : grow_coord(box->min.y, -1),
                       (k & 4) ? grow_coord(box->max.z, 1) : grow_coord(box->min.z, -1)};
        double c[4];
        for (int row = 0; row < 4; row++)
            c[row] = (double)v->vp.m[row] * p[0] + (double)v->vp.m[4 + row] * p[1] + (double)v->vp.m[8 + row] * p[2] +
                     (double)v->vp.m[12 + row];
        if (!(c[3] > 0.0) || !isfinite(c[0]) || !isfinite(c[1]))
            return false;
        xy[2 * k] = (c[0] / c[3] + 1.0) * 0.5 * W;
        xy[2 * k + 1] = (1.0 - c[1] / c[3]) * 0.5 * H;
    }
    /* pixel centres within 1/64 pixel of the silhouette count as covered: the oracle's vertex
     * snapping moves edges by at most 1/512 pixel */
    const double eps = SL_MARGIN_CENTRE_PX;
    /* first the rectangle of the pixel centres the corners' bounding box covers: it leaves out the
     * border rows and columns the box touches without covering a centre (one query) */
    double lx = xy[0], hx = xy[0], ly = xy[1], hy = xy[1];
    for (int k = 1; k < 8; k++) {
        lx = xy[2 * k] < lx ? xy[2 * k] : lx;
        hx = xy[2 * k] > hx ? xy[2 * k] : hx;
        ly = xy[2 * k + 1] < ly ? xy[2 * k + 1] : ly;
        hy = xy[2 * k + 1] > hy ? xy[2 * k + 1] : hy;
    }
    double cx0 = ceil(lx - eps - 0.5), cx1 = floor(hx + eps - 0.5);
    double cy0 = ceil(ly - eps - 0.5), cy1 = floor(hy + eps - 0.5);
    cx0 = cx0 > r->x0 ? cx0 : r->x0;
    cy0 = cy0 > r->y0 ? cy0 : r->y0;
    cx1 = cx1 < r->x1 - 1 ? cx1 : r->x1 - 1;
    cy1 = cy1 < r->y1 - 1 ? cy1 : r->y1 - 1;
    if (cx0 > cx1 || cy0 > cy1)
        return true; /* no pixel centre at all */
    for (uint32_t l = 0; l < layer_count; l++)
        if (layers[l]->occluders_rendered &&
            sl_occ_raster_test(layers[l], (int32_t)cx0, (int32_t)cy0, (int32_t)cx1 + 1, (int32_t)cy1 + 1, r->dnear) !=
                SL_RASTER_VISIBLE)
            return true;
    if ((uint32_t)(r->y1 - r->y0) > max_rows)
        return false;
    double rd = -1.0; /* the box's largest oracle depth, computed when first needed */
    double h[16];
    uint32_t m = sl_convex_hull8(xy, 8, h);
    int32_t y = r->y0;
    while (y < r->y1) {
        /* one query per group of rows inside one 4-row band of subtiles: the union of the rows'
         * spans (the rectangle test is monotone, so a hidden union hides each row) */
        int32_t yend = ((y >> 2) + 1) << 2;
        if (yend > r->y1)
            yend = r->y1;
        int32_t qx0 = INT32_MAX, qx1 = INT32_MIN, qy0 = INT32_MAX, qy1 = INT32_MIN;
        int32_t span[4][2], npx = 0;
        for (int32_t row = y; row < yend; row++) {
            span[row - y][0] = 0;
            span[row - y][1] = -1;
            double yc = row + 0.5, xl, xr;
            if (!sl_band_extent(h, m, yc - eps, yc + eps, &xl, &xr))
                continue;
            /* columns whose centre c + 0.5 lies in [xl - eps, xr + eps] */
            double ca = ceil(xl - eps - 0.5), cb = floor(xr + eps - 0.5);
            ca = fmax(ca, r->x0);
            cb = fmin(cb, r->x1 - 1);
            if (ca > cb)
                continue;
            span[row - y][0] = (int32_t)ca;
            span[row - y][1] = (int32_t)cb;
            npx += (int32_t)(cb - ca) + 1;
            qx0 = qx0 < (int32_t)ca ? qx0 : (int32_t)ca;
            qx1 = qx1 > (int32_t)cb + 1 ? qx1 : (int32_t)cb + 1;
            qy0 = qy0 < row ? qy0 : row;
            qy1 = row + 1;
        }
        if (qx0 < qx1) {
            bool hid = false;
            for (uint32_t l = 0; l < layer_count && !hid; l++)
                hid = layers[l]->occluders_rendered &&
                      sl_occ_raster_test(layers[l], qx0, qy0, qx1, qy1, r->dnear) != SL_RASTER_VISIBLE;
            /* pixel by pixel: each centre hidden in some layer or in the exact layer */
            for (int32_t row = y; row < yend && !hid && npx <= 64; row++)
                for (int32_t x = span[row - y][0]; x <= span[row - y][1]; x++) {
                    if (rd < 0.0)
                        rd = exact && exact->drawn ? sl_occ_exact_box_depth(exact, box) : INFINITY;
                    bool ph = sl_occ_exact_hides(exact, x, row, rd);
                    for (uint32_t l = 0; l < layer_count && !ph; l++)
                        ph = layers[l]->occluders_rendered &&
                             sl_occ_raster_test(layers[l], x, row, x + 1, row + 1, r->dnear) != SL_RASTER_VISIBLE;
                    if (!ph)
                        return false;
                }
            if (!hid && npx > 64)
                return false;
        }
        y = yend;
    }
    return true;
}

bool sl_occ_object_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact, sl_scene scene,
                          const sl_occ_view *v, uint32_t object, const sl_aabb *box, const sl_occ_mesh_tests *t,
                          uint64_t *tests)
{
    const struct sl_scene_t *sc = scene;
    uint32_t tris = sl_scene_meshes(sc)[sl_scene_objects(sc)[object].mesh].triangle_count;
    if ((tris > t->mesh_test && tris > t->sample_tris) || sl_occ_point_in_box(v->eye, box, 0.0f))
        return false;
    if (tests)
        (*tests)++;
    /* the object is hidden when either test hides it; the pixel-centre test goes first (cheaper,
     * and it answers most small objects) */
    sl_occ_rect r;
    if (tris <= t->sample_tris && sl_occ_project_box(v, box, &r) == SL_OCC_RECT &&
        (int64_t)(r.x1 - r.x0) * (r.y1 - r.y0) <= t->sample_px &&
        sl_occ_test_object_sampled(layers, layer_count, exact, scene, v, object, &r) != SL_RASTER_VISIBLE)
        return true;
    if (tris <= t->mesh_test)
        for (uint32_t l = 0; l < layer_count; l++)
            if (layers[l]->occluders_rendered &&
                sl_occ_raster_test_object(layers[l], scene, v, object) != SL_RASTER_VISIBLE)
                return true;
    return false;
}

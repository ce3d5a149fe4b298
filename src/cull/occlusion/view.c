/* The frame's view (sl_occ_view from a camera), the near-region test and box projection to a
 * pixel rectangle (view.h). */
#include "view.h"

#include "project.h"

#include <math.h>

/* ---- the view ---- */

void sl_occ_view_init(sl_occ_view *v, const sl_view *view)
{
    memset(v, 0, sizeof *v);
    v->view = *view;
    v->vp = view->view_proj;
    v->eye = view->eye;
    v->fwd = view->forward;
    v->fr = view->frustum;
    for (int i = 0; i < 6; i++)
        v->slack[i] = sl_margin_plane_slack(v->fr.planes[i].d);
    v->ortho = view->projection == SL_ORTHOGRAPHIC;
    v->width = view->width;
    v->height = view->height;
    v->depth = v->ortho ? SL_RASTER_DEPTH_LINEAR_Z : SL_RASTER_DEPTH_INV_W;
    /* off-axis or non-square pixels: per axis; each use takes the one that keeps its guarantee */
    v->focal = (float)fmin(view->focal_x, view->focal_y);
    v->focal_max = (float)fmax(view->focal_x, view->focal_y);
    /* the near region's reach: the farthest near-rectangle corner (exact, in double), grown for
     * the float corners and the float matrix the renderer clips with */
    double nr = v->ortho ? 0 : view->near_corner_dist;
    double mag = fabs((double)v->eye.x) + fabs((double)v->eye.y) + fabs((double)v->eye.z);
    v->near_reach = (float)sl_margin_near_grow(nr, mag);
    v->near_depth = (float)sl_margin_near_grow(view->near_plane, mag);
}

bool sl_occ_near_clear(const sl_occ_view *v, const sl_aabb *b)
{
    float zmin, zmax;
    sl_occ_box_zrange(v, b, &zmin, &zmax);
    if (zmin > v->near_depth)
        return true;
    if (v->ortho)
        return false;
    float dx = sl_occ_maxf(sl_occ_maxf(b->min.x - v->eye.x, v->eye.x - b->max.x), 0.0f);
    float dy = sl_occ_maxf(sl_occ_maxf(b->min.y - v->eye.y, v->eye.y - b->max.y), 0.0f);
    float dz = sl_occ_maxf(sl_occ_maxf(b->min.z - v->eye.z, v->eye.z - b->max.z), 0.0f);
    return dx * dx + dy * dy + dz * dz > v->near_reach * v->near_reach;
}

/* Pixel range [lo, hi) of every pixel an interval [a, b] touches, grown by 1/64 pixel and clamped
 * to [0, n] (the rasterizer's own rule for box queries). */
static void touched(float a, float b, int32_t n, int32_t *lo, int32_t *hi)
{
    const float eps = SL_MARGIN_RECT_PX;
    float fa = floorf(a - eps), fb = floorf(b + eps) + 1.0f;
    fa = fa < 0.0f ? 0.0f : (fa > (float)n ? (float)n : fa);
    fb = fb < 0.0f ? 0.0f : (fb > (float)n ? (float)n : fb);
    *lo = (int32_t)fa;
    *hi = (int32_t)fb;
}

int sl_occ_project_box(const sl_occ_view *v, const sl_aabb *b, sl_occ_rect *r)
{
    const float *m = v->vp.m;
    r->x0 = 0;
    r->y0 = 0;
    r->x1 = (int32_t)v->width;
    r->y1 = (int32_t)v->height;
    r->dnear = INFINITY;
    /* clip = M * (x, y, z, 1): the corners from the min corner plus the three edge vectors */
    float base[4], ex[4], ey[4], ez[4];
    float dx = b->max.x - b->min.x, dy = b->max.y - b->min.y, dz = b->max.z - b->min.z;
    for (int i = 0; i < 4; i++) {
        base[i] = m[i] * b->min.x + m[4 + i] * b->min.y + m[8 + i] * b->min.z + m[12 + i];
        ex[i] = m[i] * dx;
        ey[i] = m[4 + i] * dy;
        ez[i] = m[8 + i] * dz;
    }
    unsigned all = 63;
    bool near_cross = false;
    float minx = INFINITY, maxx = -INFINITY, miny = INFINITY, maxy = -INFINITY, dn = -INFINITY;
    const float hw = 0.5f * (float)v->width, hh = 0.5f * (float)v->height;
    for (int k = 0; k < 8; k++) {
        float c[4];
        for (int i = 0; i < 4; i++)
            c[i] = base[i] + ((k & 1) ? ex[i] : 0.0f) + ((k & 2) ? ey[i] : 0.0f) + ((k & 4) ? ez[i] : 0.0f);
        float x = c[0], y = c[1], z = c[2], w = c[3];
        if (!isfinite(x) || !isfinite(y) || !isfinite(z) || !isfinite(w))
            return SL_OCC_NEAR;
        unsigned o = (x < -w ? 1u : 0u) | (x > w ? 2u : 0u) | (y < -w ? 4u : 0u) | (y > w ? 8u : 0u) |
                     (z < -w ? 16u : 0u) | (z > w ? 32u : 0u);
        all &= o;
        if (z < -w || w < 1e-5f) {
            near_cross = true;
            continue;
        }
        float inv = 1.0f / w;
        float sx = (x * inv) * hw + hw, sy = hh - (y * inv) * hh;
        float d = v->ortho ? 0.5f * (1.0f - z * inv) : inv;
        minx = sl_occ_minf(minx, sx);
        maxx = sl_occ_maxf(maxx, sx);
        miny = sl_occ_minf(miny, sy);
        maxy = sl_occ_maxf(maxy, sy);
        dn = sl_occ_maxf(dn, d);
    }
    if (all)
        return SL_OCC_OUT;
    if (near_cross)
        return SL_OCC_NEAR;
    if (!isfinite(minx) || !isfinite(maxx) || !isfinite(miny) || !isfinite(maxy) || !isfinite(dn))
        return SL_OCC_NEAR;
    touched(minx, maxx, (int32_t)v->width, &r->x0, &r->x1);
    touched(miny, maxy, (int32_t)v->height, &r->y0, &r->y1);
    if (r->x0 >= r->x1 || r->y0 >= r->y1)
        return SL_OCC_OUT;
    /* the nearest corner's depth, nudged nearer to cover the rounding of the transform */
    r->dnear = dn + fabsf(dn) * SL_MARGIN_REL_F;
    return SL_OCC_RECT;
}

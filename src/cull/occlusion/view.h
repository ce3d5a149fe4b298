/* The per-frame view every occlusion method culls from (sl_occ_view: the camera's matrix, eye,
 * frustum with slacks, focal length, depth convention and near region), box projection to a pixel
 * rectangle with its nearest depth, the near-region test and the frustum classification with
 * plane masks; the pixel inset SL_OCC_MIN_INSET_PX and the float min/max every file uses. */
#ifndef SL_CULL_OCCLUSION_VIEW_H
#define SL_CULL_OCCLUSION_VIEW_H

#include "core/sl_core.h"
#include "sightline/camera.h"
#include "sightline/view.h"
#include "sightline/raster.h"

#include <math.h>

/* Pixels a prism proxy must lie inside its object's silhouette: 8 times the combined snapping
 * error of the rasterizer and the oracle (1/512 pixel each, plus float transform rounding). */
#define SL_OCC_MIN_INSET_PX SL_MARGIN_INSET_PX /* core/margins.h */

/* Branch-free float min/max without libm's NaN rules (compiles to minss/maxss; with a NaN they
 * return the second argument). */
static inline float sl_occ_minf(float a, float b) { return a < b ? a : b; }
static inline float sl_occ_maxf(float a, float b) { return a > b ? a : b; }

/* ---- the frame's view ---- */

typedef struct sl_occ_view {
    sl_view view;             /* the frame's view (finite far plane) */
    sl_mat4 vp;               /* world to clip (float, what the rasterizer is given) */
    sl_vec3 eye, fwd;
    sl_frustum fr;
    float slack[6];           /* plane slack (sl_margin_plane_slack) */
    bool ortho;
    float focal;              /* pixels per metre at unit forward distance (perspective), or pixels
                                 per metre (orthographic): the smaller of the view's x and y focal
                                 lengths (the larger pixel footprint: margins in metres that must
                                 cover some pixels) */
    float focal_max;          /* the larger of the two (pixel counts that must cover some metres) */
    uint32_t width, height;
    sl_raster_depth depth;    /* INV_W for perspective, LINEAR_Z for orthographic */
    /* the near region (the points nearer than the near plane that a pixel's ray can pass): every
     * such point lies at forward depth below near_depth and (perspective) within near_reach of
     * the eye, both grown for rounding */
    float near_depth, near_reach;
} sl_occ_view;

/* Fill a view from a validated view with a finite far plane. */
void sl_occ_view_init(sl_occ_view *v, const sl_view *view);

/* A box's screen footprint: the half-open pixel rectangle of every pixel its projection touches
 * (grown by 1/64 pixel for rounding) and the depth of its nearest point in the rasterizer's
 * convention (larger = nearer), nudged nearer by 2^-20 relative. */
typedef struct sl_occ_rect {
    int32_t x0, y0, x1, y1;
    float dnear;
} sl_occ_rect;

enum {
    SL_OCC_OUT = 0,    /* beyond a frustum plane (or off screen): invisible */
    SL_OCC_RECT = 1,   /* rect and dnear are valid */
    SL_OCC_NEAR = 2    /* crosses the near plane, contains the eye or is not finite: treat as visible,
                          rect is the whole screen and dnear +infinity */
};

/* Project box b. Returns SL_OCC_OUT, SL_OCC_RECT or SL_OCC_NEAR. */
int sl_occ_project_box(const sl_occ_view *v, const sl_aabb *b, sl_occ_rect *r);

/* Forward (eye-space) depth range of a box: min and max of dot(fwd, p - eye) over its corners. */
static inline void sl_occ_box_zrange(const sl_occ_view *v, const sl_aabb *b, float *zmin, float *zmax)
{
    const float f[3] = {v->fwd.x, v->fwd.y, v->fwd.z};
    const float lo[3] = {b->min.x - v->eye.x, b->min.y - v->eye.y, b->min.z - v->eye.z};
    const float hi[3] = {b->max.x - v->eye.x, b->max.y - v->eye.y, b->max.z - v->eye.z};
    float a = 0, c = 0;
    for (int i = 0; i < 3; i++) {
        float p = f[i] * lo[i], q = f[i] * hi[i];
        a += p < q ? p : q;
        c += p < q ? q : p;
    }
    *zmin = a;
    *zmax = c;
}

/* Does box b keep out of the view's near region (no point of it nearer than the near plane on a
 * pixel's ray)? Conservative: may say no for a box that does. */
bool sl_occ_near_clear(const sl_occ_view *v, const sl_aabb *b);

/* Frustum classification with plane masks (as vfc): -1 outside, else the mask of the planes the
 * box straddles (0: wholly inside). */
static inline int sl_occ_frustum_classify(const sl_occ_view *v, const sl_aabb *b, uint32_t mask)
{
    return sl_frustum_classify_box(v->fr.planes, v->slack, b, mask, true, NULL);
}

/* True when point p lies in box b grown by g. */
static inline bool sl_occ_point_in_box(sl_vec3 p, const sl_aabb *b, float g)
{
    return p.x >= b->min.x - g && p.x <= b->max.x + g && p.y >= b->min.y - g && p.y <= b->max.y + g &&
           p.z >= b->min.z - g && p.z <= b->max.z + g;
}

#endif

/* Internal to src/cull/occlusion/: the double-precision transforms and projections that several
 * occlusion files share (the occluder rendering, the raster wrapper, the object tests and the exact
 * layer): a box coordinate grown outward, model-to-clip in double and in float, an object's current
 * transform and mesh, a vertex projected to the screen, and the oracle's reversed depth. Inline, so
 * every caller computes the same bits as before the split (they were static in occluders.c). */
#ifndef SL_CULL_OCCLUSION_PROJECT_H
#define SL_CULL_OCCLUSION_PROJECT_H

#include "cull/occlusion/view.h"
#include "scene/scene_internal.h"

#include <math.h>

/* A vertex projected in double precision (MESH occluders, pixel-centre tests). */
typedef struct sl_occ_screen_vertex {
    double x, y;              /* screen position (pixels) */
    float d;                  /* depth in the rasterizer's convention (larger = nearer) */
    bool ok;                  /* in front of the eye (w > 1e-5) and finite */
    bool between;             /* and between the near and far planes */
} sl_occ_screen_vertex;

/* A box coordinate pushed outward by 2^-20 of its magnitude (plus 2^-20 m): object boxes are
 * transformed in float, the oracle transforms vertices in double, so a vertex may lie an ulp or
 * two outside its object's box. */
static inline double grow_coord(float c, double dir)
{
    return (double)c + dir * (fabs((double)c) + 1.0) * SL_MARGIN_REL;
}

/* model-to-clip = vp * affine, in double, rounded once */
/* model-to-clip = vp * affine in double (column-major, m[col * 4 + row]) */
static inline void mul_affine_d(const sl_mat4 *vp, const sl_affine *t, double out[16])
{
    double a4[16] = {0};
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++)
            a4[c * 4 + r] = t->m[4 * r + c];
    a4[15] = 1;
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 4; r++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += (double)vp->m[k * 4 + r] * a4[c * 4 + k];
            out[c * 4 + r] = s;
        }
}

/* the same rounded once to float (what the rasterizer is given) */
static inline void mul_affine(const sl_mat4 *vp, const sl_affine *t, float out[16])
{
    double d[16];
    mul_affine_d(vp, t, d);
    for (int i = 0; i < 16; i++)
        out[i] = (float)d[i];
}

static inline sl_affine object_transform(const struct sl_scene_t *sc, uint32_t object)
{
    uint32_t t = sl_scene_objects(sc)[object].transform;
    return t == SL_NONE ? sl_affine_identity() : sl_scene_transforms(sc)[t];
}

/* An object's mesh: its record, vertices, indices and current transform. */
typedef struct object_mesh {
    const sl_mesh_rec *mr;
    const float *pos;
    const uint32_t *idx;
    sl_affine xf;
} object_mesh;

static inline object_mesh get_object_mesh(const struct sl_scene_t *sc, uint32_t object)
{
    object_mesh o;
    o.mr = &sl_scene_meshes(sc)[sl_scene_objects(sc)[object].mesh];
    o.pos = sl_scene_positions(sc) + 3 * o.mr->first_vertex;
    o.idx = sl_scene_indices(sc) + o.mr->first_index;
    o.xf = object_transform(sc, object);
    return o;
}

static inline sl_occ_screen_vertex project_vertex(const sl_occ_view *v, const double m[16], const float *p)
{
    sl_occ_screen_vertex o = {0, 0, 0, false, false};
    double cl[4];
    for (int r = 0; r < 4; r++)
        cl[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
    if (!(cl[3] > 1e-5) || !isfinite(cl[0]) || !isfinite(cl[1]) || !isfinite(cl[2]))
        return o;
    o.between = cl[2] >= -cl[3] && cl[2] <= cl[3];
    double inv = 1.0 / cl[3];
    o.x = (cl[0] * inv + 1.0) * 0.5 * (double)v->width;
    o.y = (1.0 - cl[1] * inv) * 0.5 * (double)v->height;
    o.d = (float)(v->ortho ? 0.5 * (1.0 - cl[2] * inv) : inv);
    o.ok = true;
    return o;
}

/* Reversed depth of a clip-space point exactly as the oracle computes a vertex's (raster_ref.c). */
static inline double oracle_depth(const double c[4])
{
    double inv = 1.0 / c[3];
    double d = 0.5 * (1.0 - c[2] * inv);
    return d < 0 ? 0 : d > 1 ? 1 : d;
}

#endif

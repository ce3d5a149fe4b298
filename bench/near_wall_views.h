/* Near-wall views (issue 12 §1), shared by tests/test_near_wall.c and bench/near_wall.c.
 *
 * A view is placed the way a player pressed against a wall sees: a random point on a random
 * triangle of the scene (area-weighted over every object's triangles, with its current
 * transform), stepped out along the triangle's front normal by a random distance in
 * [dmin, dmax] metres (0.001-0.2 m by default, inside the reach of the 0.1 m near plane, whose
 * frustum corners lie 0.139 m from the eye at 60 degrees), looking in a random direction of the
 * surface's half-space tilted further towards the surface, so that the near plane usually cuts it.
 * A quarter of the views are rolled. On a Quake III map an eye outside every cluster (solid or
 * void space) is drawn again. Deterministic: a splitmix64 stream per seed, no global state.
 *
 * Header-only (static functions) so that both a test and a bench program can use it. */
#ifndef SL_BENCH_NEAR_WALL_VIEWS_H
#define SL_BENCH_NEAR_WALL_VIEWS_H

#include "core/dvec3.h"
#include "sightline/camera.h"
#include "sightline/scene.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct nw_rng {
    uint64_t s;
} nw_rng;

static inline uint64_t nw_next(nw_rng *r)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Uniform in [0, 1). */
static inline double nw_unit(nw_rng *r) { return (double)(nw_next(r) >> 11) * (1.0 / 9007199254740992.0); }

/* The scene's triangles with their cumulative areas, for area-weighted picking. */
typedef struct nw_table {
    uint32_t count;
    uint32_t *object, *tri;
    double *cum;              /* cumulative area up to and including entry i */
} nw_table;

static inline void nw_corners(sl_scene s, uint32_t object, uint32_t t, sl_vec3 p[3])
{
    sl_object_view ov = sl_scene_object(s, object);
    sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
    for (int k = 0; k < 3; k++) {
        const float *q = mv.positions + 3 * (size_t)mv.indices[3 * (size_t)t + (size_t)k];
        p[k] = sl_affine_point(&ov.transform, (sl_vec3){q[0], q[1], q[2]});
    }
}

/* Build the table (false when out of memory or the scene has no triangle of positive area). */
static inline bool nw_table_build(sl_scene s, nw_table *tb)
{
    uint32_t n = sl_scene_object_count(s);
    uint64_t total = 0;
    for (uint32_t i = 0; i < n; i++)
        total += sl_scene_object(s, i).triangle_count;
    tb->count = 0;
    tb->object = malloc((size_t)(total ? total : 1) * sizeof(uint32_t));
    tb->tri = malloc((size_t)(total ? total : 1) * sizeof(uint32_t));
    tb->cum = malloc((size_t)(total ? total : 1) * sizeof(double));
    if (!tb->object || !tb->tri || !tb->cum)
        return false;
    double acc = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t tc = sl_scene_object(s, i).triangle_count;
        for (uint32_t t = 0; t < tc; t++) {
            sl_vec3 p[3];
            nw_corners(s, i, t, p);
            double a = 0.5 * sl_v3_len(sl_v3_cross(sl_v3_sub(p[1], p[0]), sl_v3_sub(p[2], p[0])));
            if (!(a > 1e-6) || !isfinite(a))
                continue;
            acc += a;
            tb->object[tb->count] = i;
            tb->tri[tb->count] = t;
            tb->cum[tb->count] = acc;
            tb->count++;
        }
    }
    return tb->count > 0;
}

static inline void nw_table_free(nw_table *tb)
{
    free(tb->object);
    free(tb->tri);
    free(tb->cum);
    tb->object = tb->tri = NULL;
    tb->cum = NULL;
    tb->count = 0;
}

/* One near-wall camera from the intrinsics of `in` (projection, fov, planes, size). Returns the
 * distance stepped out, or a negative value when no valid eye was found in 64 draws. */
static inline double nw_view(sl_scene s, const nw_table *tb, nw_rng *r, const sl_camera *in, double dmin,
                             double dmax, sl_camera *out)
{
    sl_bsp_view bsp;
    bool has_bsp = sl_scene_bsp(s, &bsp);
    for (int attempt = 0; attempt < 64; attempt++) {
        double u = nw_unit(r) * tb->cum[tb->count - 1];
        uint32_t lo = 0, hi = tb->count - 1;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2;
            if (tb->cum[mid] < u)
                lo = mid + 1;
            else
                hi = mid;
        }
        sl_vec3 p[3];
        nw_corners(s, tb->object[lo], tb->tri[lo], p);
        sl_vec3 nv = sl_v3_cross(sl_v3_sub(p[1], p[0]), sl_v3_sub(p[2], p[0]));
        double nl = sl_v3_len(nv);
        if (!(nl > 0))
            continue;
        double n[3] = {nv.x / nl, nv.y / nl, nv.z / nl};
        double a = nw_unit(r), b = nw_unit(r);
        if (a + b > 1)
            a = 1 - a, b = 1 - b;
        double d = dmin + (dmax - dmin) * nw_unit(r);
        double e[3];
        const float *c0 = &p[0].x, *c1 = &p[1].x, *c2 = &p[2].x;
        for (int k = 0; k < 3; k++)
            e[k] = c0[k] + a * (c1[k] - c0[k]) + b * (c2[k] - c0[k]) + d * n[k];
        sl_vec3 eye = {(float)e[0], (float)e[1], (float)e[2]};
        if (has_bsp) {
            int32_t leaf = sl_scene_bsp_find_leaf(s, eye);
            if (leaf < 0 || (uint32_t)leaf >= bsp.leaf_count || bsp.leaves[leaf].cluster < 0)
                continue;
        }
        /* a random direction of the surface's side, tilted towards the surface */
        double v[3], vl;
        do {
            for (int k = 0; k < 3; k++)
                v[k] = 2 * nw_unit(r) - 1;
            vl = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        } while (!(vl > 1e-3 && vl <= 1));
        double vn = (v[0] * n[0] + v[1] * n[1] + v[2] * n[2]) / vl;
        for (int k = 0; k < 3; k++)
            v[k] = v[k] / vl - (vn > 0 ? 2 * vn * n[k] : 0) - 0.5 * n[k];
        vl = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (!(vl > 1e-6))
            continue;
        *out = *in;
        out->position = eye;
        double pz = v[2] / vl;
        pz = pz > 1 ? 1 : pz < -1 ? -1 : pz;
        out->pitch = (float)asin(pz);
        out->yaw = (float)atan2(v[1], v[0]);
        out->roll = nw_unit(r) < 0.25 ? (float)((2 * nw_unit(r) - 1) * 3.14159265358979) : 0.0f;
        /* keep pitch strictly inside [-pi/2, pi/2] after float rounding */
        if (out->pitch > 1.5707f)
            out->pitch = 1.5707f;
        if (out->pitch < -1.5707f)
            out->pitch = -1.5707f;
        return d;
    }
    return -1;
}

#endif

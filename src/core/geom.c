/* Value-type geometry helpers of the public API. */
#include "sl_core.h"

#include <math.h>

sl_aabb sl_aabb_empty(void)
{
    sl_aabb b = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
    return b;
}

void sl_aabb_grow(sl_aabb *b, sl_vec3 p)
{
    b->min.x = fminf(b->min.x, p.x);
    b->min.y = fminf(b->min.y, p.y);
    b->min.z = fminf(b->min.z, p.z);
    b->max.x = fmaxf(b->max.x, p.x);
    b->max.y = fmaxf(b->max.y, p.y);
    b->max.z = fmaxf(b->max.z, p.z);
}

void sl_aabb_merge(sl_aabb *b, const sl_aabb *o)
{
    sl_aabb_grow(b, o->min);
    sl_aabb_grow(b, o->max);
}

bool sl_aabb_is_empty(const sl_aabb *b) { return !(b->min.x <= b->max.x && b->min.y <= b->max.y && b->min.z <= b->max.z); }

sl_affine sl_affine_identity(void)
{
    sl_affine t = {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
    return t;
}

sl_vec3 sl_affine_point(const sl_affine *t, sl_vec3 p)
{
    const float *m = t->m;
    sl_vec3 r = {m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                 m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]};
    return r;
}

sl_aabb sl_aabb_transform(const sl_aabb *b, const sl_affine *t)
{
    if (sl_aabb_is_empty(b))
        return *b;
    /* Arvo's method: each output extent is the sum of per-axis min/max contributions */
    sl_aabb r;
    const float *m = t->m;
    float lo[3], hi[3];
    const float bmin[3] = {b->min.x, b->min.y, b->min.z}, bmax[3] = {b->max.x, b->max.y, b->max.z};
    for (int i = 0; i < 3; i++) {
        lo[i] = hi[i] = m[i * 4 + 3];
        for (int j = 0; j < 3; j++) {
            float e = m[i * 4 + j] * bmin[j], f = m[i * 4 + j] * bmax[j];
            lo[i] += fminf(e, f);
            hi[i] += fmaxf(e, f);
        }
    }
    r.min = (sl_vec3){lo[0], lo[1], lo[2]};
    r.max = (sl_vec3){hi[0], hi[1], hi[2]};
    return r;
}

uint32_t sl_convex_hull8(const double *xy, uint32_t n, double *hull)
{
    if (n == 0)
        return 0;
    n = n > 8 ? 8 : n;
    double p[8][2];
    for (uint32_t i = 0; i < n; i++) { /* insertion sort by x, then y */
        uint32_t j = i;
        for (; j > 0 && (xy[2 * i] < p[j - 1][0] || (xy[2 * i] == p[j - 1][0] && xy[2 * i + 1] < p[j - 1][1])); j--) {
            p[j][0] = p[j - 1][0];
            p[j][1] = p[j - 1][1];
        }
        p[j][0] = xy[2 * i];
        p[j][1] = xy[2 * i + 1];
    }
    double h[18][2];
    uint32_t k = 0;
    for (int pass = 0; pass < 2; pass++) { /* lower chain, then upper chain */
        uint32_t start = k;
        for (uint32_t q = 0; q < n; q++) {
            const double *c = p[pass == 0 ? q : n - 1 - q];
            while (k >= start + 2) {
                const double *o = h[k - 2], *a = h[k - 1];
                if ((a[0] - o[0]) * (c[1] - o[1]) - (a[1] - o[1]) * (c[0] - o[0]) > 0)
                    break;
                k--;
            }
            h[k][0] = c[0];
            h[k][1] = c[1];
            k++;
        }
        k--; /* the last point starts the other chain */
    }
    if (k < 1) {
        h[0][0] = p[0][0];
        h[0][1] = p[0][1];
        k = 1;
    }
    for (uint32_t i = 0; i < k; i++) {
        hull[2 * i] = h[i][0];
        hull[2 * i + 1] = h[i][1];
    }
    return k;
}

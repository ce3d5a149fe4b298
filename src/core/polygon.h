/* Internal: 2D polygon geometry in double precision that is not about occlusion (moved out of
 * src/cull/occluders.c, issue 13 section 5): offsetting a simple polygon inward with a certificate,
 * ear clipping, merging triangles into convex pieces (Hertel-Mehlhorn), clipping a convex polygon by
 * a half-plane and the x extent of a convex polygon within a horizontal band. The last two are
 * inline (they run per face and per row band of the occlusion methods). */
#ifndef SL_CORE_POLYGON_H
#define SL_CORE_POLYGON_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

typedef struct {
    double x, y;
} sl_dvec2;

/* Offset the counter-clockwise simple polygon p[0..n) inward by d into q, and check that every
 * point of q lies at least d (less a relative 1e-6) from p's boundary and inside p: q simple, its
 * edges parallel to p's and pointing the same way, every pair of edges at least d apart, and its
 * first vertex inside p. False when the offset collapses or cannot be certified. */
bool sl_inset_polygon(const sl_dvec2 *p, uint32_t n, double d, sl_dvec2 *q);

/* Ear-clip the counter-clockwise simple polygon q[0..n) into n-2 triangles (tri, 3 each; work: n
 * entries). */
bool sl_ear_clip(const sl_dvec2 *q, uint32_t n, uint32_t *work, uint32_t *tri);

/* Merge the triangles of sl_ear_clip into convex polygons (Hertel-Mehlhorn: drop a diagonal while
 * both polygons it separates stay convex). polys: up to n-2 polygons of up to n vertex indices each,
 * stored with stride n; len[i] = 0 for merged-away ones. */
void sl_merge_convex(const sl_dvec2 *q, uint32_t n, const uint32_t *tri, uint32_t *polys, uint32_t *len);

/* Clip convex polygon (px, py, n) by the half-plane nx x + ny y >= off into (qx, qy); returns the
 * count. An intersection is computed from the segment's endpoints in a fixed order, so two faces
 * sharing an edge get the same points. */
static inline uint32_t sl_clip_half(const double *px, const double *py, uint32_t n, double nx, double ny, double off,
                                    double *qx, double *qy, uint32_t cap)
{
    uint32_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        double si = nx * px[i] + ny * py[i] - off, sj = nx * px[j] + ny * py[j] - off;
        bool in_i = si >= 0, in_j = sj >= 0;
        if (in_i && k < cap) {
            qx[k] = px[i];
            qy[k] = py[i];
            k++;
        }
        if (in_i != in_j && k < cap) {
            /* canonical order: from the lexicographically smaller endpoint */
            bool sw = px[j] < px[i] || (px[j] == px[i] && py[j] < py[i]);
            double ax = sw ? px[j] : px[i], ay = sw ? py[j] : py[i], bx = sw ? px[i] : px[j], by = sw ? py[i] : py[j];
            double sa = sw ? sj : si, sb = sw ? si : sj;
            double t = sa / (sa - sb);
            qx[k] = ax + (bx - ax) * t;
            qy[k] = ay + (by - ay) * t;
            k++;
        }
    }
    return k;
}

/* x extent of the convex polygon h (m vertices) within the band ya <= y <= yb: false when the band
 * misses it. */
static inline bool sl_band_extent(const double *h, uint32_t m, double ya, double yb, double *xl, double *xr)
{
    double lo = INFINITY, hi = -INFINITY;
    for (uint32_t i = 0; i < m; i++) {
        double x0 = h[2 * i], y0 = h[2 * i + 1];
        uint32_t j = i + 1 == m ? 0 : i + 1;
        double x1 = h[2 * j], y1 = h[2 * j + 1];
        if (y0 >= ya && y0 <= yb) {
            lo = x0 < lo ? x0 : lo;
            hi = x0 > hi ? x0 : hi;
        }
        double yl = y0 < y1 ? y0 : y1, yh = y0 < y1 ? y1 : y0;
        for (int e = 0; e < 2; e++) {
            double yc = e ? yb : ya;
            if (yl < yc && yc < yh) {
                double x = x0 + (x1 - x0) * (yc - y0) / (y1 - y0);
                lo = x < lo ? x : lo;
                hi = x > hi ? x : hi;
            }
        }
    }
    if (!(lo <= hi))
        return false;
    *xl = lo;
    *xr = hi;
    return true;
}

#endif

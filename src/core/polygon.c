/* 2D polygon geometry (polygon.h). */
#include "polygon.h"

#include "sl_core.h"

static double cross2(sl_dvec2 a, sl_dvec2 b) { return a.x * b.y - a.y * b.x; }
static sl_dvec2 sub2(sl_dvec2 a, sl_dvec2 b) { return (sl_dvec2){a.x - b.x, a.y - b.y}; }

static double seg_point_dist(sl_dvec2 p, sl_dvec2 a, sl_dvec2 b)
{
    sl_dvec2 ab = sub2(b, a), ap = sub2(p, a);
    double l2 = ab.x * ab.x + ab.y * ab.y, t = l2 > 0 ? (ap.x * ab.x + ap.y * ab.y) / l2 : 0;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    double dx = a.x + t * ab.x - p.x, dy = a.y + t * ab.y - p.y;
    return sqrt(dx * dx + dy * dy);
}

/* Do segments ab and cd intersect (touching counts)? */
static bool seg_intersect(sl_dvec2 a, sl_dvec2 b, sl_dvec2 c, sl_dvec2 d)
{
    double d1 = cross2(sub2(b, a), sub2(c, a)), d2 = cross2(sub2(b, a), sub2(d, a));
    double d3 = cross2(sub2(d, c), sub2(a, c)), d4 = cross2(sub2(d, c), sub2(b, c));
    if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
        return true;
    /* collinear or touching cases: close enough counts as touching */
    return seg_point_dist(c, a, b) == 0 || seg_point_dist(d, a, b) == 0 || seg_point_dist(a, c, d) == 0 ||
           seg_point_dist(b, c, d) == 0;
}

static double seg_seg_dist(sl_dvec2 a, sl_dvec2 b, sl_dvec2 c, sl_dvec2 d)
{
    if (seg_intersect(a, b, c, d))
        return 0;
    double m = seg_point_dist(a, c, d);
    m = fmin(m, seg_point_dist(b, c, d));
    m = fmin(m, seg_point_dist(c, a, b));
    return fmin(m, seg_point_dist(d, a, b));
}

static bool point_in_poly(sl_dvec2 p, const sl_dvec2 *q, uint32_t n)
{
    bool in = false;
    for (uint32_t i = 0, j = n - 1; i < n; j = i++)
        if ((q[i].y > p.y) != (q[j].y > p.y) && p.x < (q[j].x - q[i].x) * (p.y - q[i].y) / (q[j].y - q[i].y) + q[i].x)
            in = !in;
    return in;
}

/* Offset the counter-clockwise simple polygon p[0..n) inward by d into q, and check that every
 * point of q lies at least d (less a relative 1e-6) from p's boundary and inside p: q simple, its
 * edges parallel to p's and pointing the same way, every pair of edges at least d apart, and its
 * first vertex inside p. False when the offset collapses or cannot be certified. */
bool sl_inset_polygon(const sl_dvec2 *p, uint32_t n, double d, sl_dvec2 *q)
{
    for (uint32_t i = 0; i < n; i++) {
        sl_dvec2 a = p[(i + n - 1) % n], b = p[i], c = p[(i + 1) % n];
        sl_dvec2 e0 = sub2(b, a), e1 = sub2(c, b);
        double l0 = hypot(e0.x, e0.y), l1 = hypot(e1.x, e1.y);
        if (!(l0 > 0) || !(l1 > 0))
            return false;
        sl_dvec2 n0 = {-e0.y / l0, e0.x / l0}, n1 = {-e1.y / l1, e1.x / l1}; /* left = inward for CCW */
        double det = cross2(n0, n1);
        if (fabs(det) < 1e-9) {
            if (n0.x * n1.x + n0.y * n1.y < 0)
                return false; /* a spike folding back */
            q[i] = (sl_dvec2){b.x + d * n0.x, b.y + d * n0.y};
        } else {
            double c0 = n0.x * b.x + n0.y * b.y + d, c1 = n1.x * b.x + n1.y * b.y + d;
            q[i] = (sl_dvec2){(c0 * n1.y - c1 * n0.y) / det, (n0.x * c1 - n1.x * c0) / det};
        }
        if (!isfinite(q[i].x) || !isfinite(q[i].y) || hypot(q[i].x - b.x, q[i].y - b.y) > 50.0 * d)
            return false;
    }
    double area = 0;
    for (uint32_t i = 0; i < n; i++)
        area += cross2(q[i], q[(i + 1) % n]);
    if (!(area > 0))
        return false;
    for (uint32_t i = 0; i < n; i++) {
        sl_dvec2 pe = sub2(p[(i + 1) % n], p[i]), qe = sub2(q[(i + 1) % n], q[i]);
        if (!(pe.x * qe.x + pe.y * qe.y > 0) || hypot(qe.x, qe.y) < 1e-4)
            return false;
    }
    double need = d * (1.0 - 1e-6);
    for (uint32_t i = 0; i < n; i++) {
        sl_dvec2 a = q[i], b = q[(i + 1) % n];
        for (uint32_t j = 0; j < n; j++) {
            /* offset edges: non-adjacent ones must not meet */
            if (j != i && j != (i + 1) % n && (j + 1) % n != i && seg_intersect(a, b, q[j], q[(j + 1) % n]))
                return false;
            if (seg_seg_dist(a, b, p[j], p[(j + 1) % n]) < need)
                return false;
        }
    }
    return point_in_poly(q[0], p, n);
}

/* Ear-clip the counter-clockwise simple polygon q[0..n) into n-2 triangles (tri, 3 each). */
bool sl_ear_clip(const sl_dvec2 *q, uint32_t n, uint32_t *work, uint32_t *tri)
{
    for (uint32_t i = 0; i < n; i++)
        work[i] = i;
    uint32_t m = n, t = 0, guard = 0;
    while (m > 3) {
        bool found = false;
        for (uint32_t k = 0; k < m && !found; k++) {
            uint32_t ia = work[(k + m - 1) % m], ib = work[k], ic = work[(k + 1) % m];
            sl_dvec2 a = q[ia], b = q[ib], c = q[ic];
            if (!(cross2(sub2(b, a), sub2(c, b)) > 0))
                continue;
            bool empty = true;
            for (uint32_t j = 0; j < m && empty; j++) {
                uint32_t ij = work[j];
                if (ij == ia || ij == ib || ij == ic)
                    continue;
                sl_dvec2 p = q[ij];
                if (cross2(sub2(b, a), sub2(p, a)) >= 0 && cross2(sub2(c, b), sub2(p, b)) >= 0 &&
                    cross2(sub2(a, c), sub2(p, c)) >= 0)
                    empty = false;
            }
            if (!empty)
                continue;
            tri[3 * t] = ia;
            tri[3 * t + 1] = ib;
            tri[3 * t + 2] = ic;
            t++;
            for (uint32_t j = k; j + 1 < m; j++)
                work[j] = work[j + 1];
            m--;
            found = true;
        }
        if (!found || ++guard > 4 * n)
            return false;
    }
    tri[3 * t] = work[0];
    tri[3 * t + 1] = work[1];
    tri[3 * t + 2] = work[2];
    return true;
}

/* Merge the roof triangles into convex polygons (Hertel-Mehlhorn: drop a diagonal while both
 * polygons it separates stay convex). polys: up to n-2 polygons of up to n vertex indices each,
 * stored with stride n; len[i] = 0 for merged-away ones. */
void sl_merge_convex(const sl_dvec2 *q, uint32_t n, const uint32_t *tri, uint32_t *polys, uint32_t *len)
{
    uint32_t np = n - 2;
    for (uint32_t i = 0; i < np; i++) {
        memcpy(polys + (size_t)i * n, tri + 3 * i, 3 * sizeof(uint32_t));
        len[i] = 3;
    }
    bool merged = true;
    while (merged) {
        merged = false;
        for (uint32_t a = 0; a < np && !merged; a++) {
            if (!len[a])
                continue;
            for (uint32_t b = a + 1; b < np && !merged; b++) {
                if (!len[b])
                    continue;
                uint32_t *pa = polys + (size_t)a * n, *pb = polys + (size_t)b * n;
                for (uint32_t i = 0; i < len[a] && !merged; i++) {
                    uint32_t u = pa[i], w = pa[(i + 1) % len[a]];
                    for (uint32_t j = 0; j < len[b] && !merged; j++) {
                        if (pb[j] != w || pb[(j + 1) % len[b]] != u)
                            continue;
                        /* splice: pa up to u, then pb from after u around to before w, then w.. */
                        uint32_t tmp[256], k = 0;
                        if (len[a] + len[b] - 2 > 256 || len[a] + len[b] - 2 > n)
                            continue;
                        for (uint32_t s = 0; s < len[a]; s++) {
                            uint32_t v = pa[(i + 1 + s) % len[a]]; /* starts at w, ends at u */
                            tmp[k++] = v;
                        }
                        for (uint32_t s = 2; s < len[b]; s++)
                            tmp[k++] = pb[(j + s) % len[b]]; /* after u, before w */
                        bool convex = true;
                        for (uint32_t s = 0; s < k && convex; s++) {
                            sl_dvec2 x = q[tmp[s]], y = q[tmp[(s + 1) % k]], z = q[tmp[(s + 2) % k]];
                            convex = cross2(sub2(y, x), sub2(z, y)) > -1e-12;
                        }
                        if (!convex)
                            continue;
                        memcpy(pa, tmp, k * sizeof(uint32_t));
                        len[a] = k;
                        len[b] = 0;
                        merged = true;
                    }
                }
            }
        }
    }
}

/* Occluders by inner coverage (res=any, inner_coverage.h): MESH and SCENE_MESH triangles shrunk on
 * screen by the pixel footprint, prisms eroded face by face (inner=faces) or by the silhouettes of
 * their convex pieces (inner=hull), meshes by their convex parts. Moved out of occluders.c (issue
 * 13 section 5); docs/occlusion.md and docs/culler-contract.md for the rules. */
#include "inner_coverage.h"

#include "core/polygon.h"
#include "cull/convex_parts.h"
#include "project.h"

#include <math.h>

static inline double maxd(double a, double b) { return a > b ? a : b; }

/* Render a MESH proxy (an object's own triangles, two-sided) so that it covers only pixel centres
 * the oracle gives to it: each triangle is projected in double precision, shrunk on screen by
 * SL_OCC_MIN_INSET_PX (every edge moved inward: a homothety about the incentre; a triangle whose
 * inradius is smaller is dropped) and rendered at its farthest vertex depth, nudged farther. A
 * centre the rasterizer counts as covered then lies at least 1/32 pixel minus both snappings
 * (1/512 pixel each) and float rounding inside the exact triangle, so the oracle's snapped
 * triangle covers it too, and the depth written is never nearer than the triangle's there.
 * Triangles not wholly between the near and far planes are dropped (fewer occluders is safe).
 * The cost: centres within 1/32 pixel of the mesh's edges, inner edges included, are not covered. */
void sl_occ_render_mesh_shrunk(sl_occ_raster *r, const struct sl_scene_t *sc, const sl_occ_view *v, uint32_t mesh,
                               sl_affine xf, const uint32_t *tris, uint32_t ntris)
{
    const sl_mesh_rec *mr = &sl_scene_meshes(sc)[mesh];
    const float *pos = sl_scene_positions(sc) + 3 * mr->first_vertex;
    const uint32_t *idx = sl_scene_indices(sc) + mr->first_index;
    /* res=any: every edge moved inward by the pixel footprint too (half a pixel's diagonal bounds
     * (|nx| + |ny|) / 2 for any edge direction), so that a centre it covers has its whole pixel
     * inside; the depth is the farthest vertex's, valid over the whole pixel */
    const double eps = SL_OCC_MIN_INSET_PX + (r->erode ? SL_MARGIN_HALF_DIAG_PX : 0.0);
    const double W = (double)v->width, H = (double)v->height;
    /* every vertex projected once (shrunk_proj holds the largest MESH proxy's) */
    double m[16];
    mul_affine_d(&v->vp, &xf, m);
    sl_occ_screen_vertex *proj = r->shrunk_proj;
    for (uint32_t i = 0; i < mr->vertex_count; i++)
        proj[i] = project_vertex(v, m, pos + 3 * (size_t)i);
    uint32_t n = 0;
    /* tris: only these triangles (NULL: all) */
    const uint32_t nt = tris ? ntris : mr->triangle_count;
    for (uint32_t ti = 0; ti < nt && n < r->shrunk_cap; ti++) {
        const uint32_t t = tris ? tris[ti] : ti;
        double sx[3], sy[3], dfar = INFINITY;
        bool ok = true;
        for (int k = 0; k < 3 && ok; k++) {
            uint32_t vi = idx[3 * t + (uint32_t)k];
            ok = vi < mr->vertex_count && proj[vi].ok && proj[vi].between;
            if (!ok)
                break;
            sx[k] = proj[vi].x;
            sy[k] = proj[vi].y;
            dfar = proj[vi].d < dfar ? proj[vi].d : dfar;
        }
        if (!ok)
            continue;
        double ax = sx[1] - sx[2], ay = sy[1] - sy[2], bx = sx[2] - sx[0], by = sy[2] - sy[0];
        double cx = sx[0] - sx[1], cy = sy[0] - sy[1];
        double area2 = fabs((sx[1] - sx[0]) * (sy[2] - sy[0]) - (sy[1] - sy[0]) * (sx[2] - sx[0]));
        /* most far triangles are too thin: the perimeter is at least twice the longest edge, at
         * least twice its largest coordinate difference, so inradius <= area2 / (2 * that); with a
         * relative margin far above the rounding below, such a triangle is dropped by the exact
         * test too, and the square roots are skipped */
        double span = maxd(maxd(maxd(fabs(ax), fabs(ay)), maxd(fabs(bx), fabs(by))), maxd(fabs(cx), fabs(cy)));
        if (area2 <= 2.0 * eps * span * (1.0 - 1e-9))
            continue;
        double la = sqrt(ax * ax + ay * ay), lb = sqrt(bx * bx + by * by), lc = sqrt(cx * cx + cy * cy);
        double per = la + lb + lc;
        double inr = per > 0 ? area2 / per : 0; /* inradius = area / semi-perimeter */
        if (!(inr > eps) || !isfinite(inr) || !(dfar > 0))
            continue;
        double ix = (la * sx[0] + lb * sx[1] + lc * sx[2]) / per, iy = (la * sy[0] + lb * sy[1] + lc * sy[2]) / per;
        double scale = (inr - eps) / inr;
        /* the farthest depth, nudged farther against rounding */
        float d = (float)(dfar * (1.0 - SL_MARGIN_REL));
        float *o = r->shrunk + 9 * (size_t)n;
        for (int k = 0; k < 3; k++) {
            double px = ix + (sx[k] - ix) * scale, py = iy + (sy[k] - iy) * scale;
            double nx = 2.0 * px / W - 1.0, ny = 1.0 - 2.0 * py / H;
            /* input (x_clip, y_clip, c) mapped by g_shrunk_m: perspective w = 1/d, z = 0;
             * orthographic w = 1, z = 1 - 2d */
            double w = v->ortho ? 1.0 : 1.0 / (double)d;
            o[3 * k] = (float)(nx * w);
            o[3 * k + 1] = (float)(ny * w);
            o[3 * k + 2] = v->ortho ? (float)(1.0 - 2.0 * (double)d) : (float)w;
        }
        n++;
    }
    if (!n)
        return;
    /* columns: clip = (a, b, 0, c) perspective; (a, b, c, 1) orthographic */
    static const float m_persp[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0};
    static const float m_ortho[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    const float *to_clip = v->ortho ? m_ortho : m_persp;
    (void)sl_raster_render_triangles(r->ctx, r->shrunk, 3 * n, r->shrunk_idx, n, 12, to_clip, SL_RASTER_CULL_NONE,
                                     NULL);
    if (r->rec)
        sl_occ_recorder_batch(r->rec, r->shrunk, 12, r->shrunk_idx, n, to_clip, SL_RASTER_CULL_NONE);
}

/* Clip-space input of the shrunk batches, mapped by these (columns): clip = (a, b, 0, c)
 * perspective (depth 1/w = 1/c); (a, b, c, 1) orthographic (depth (1 - c) / 2). */
static const float g_shrunk_persp[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0};
static const float g_shrunk_ortho[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

/* Draw the first n triangles of r->shrunk (clip-space input of g_shrunk_persp/_ortho). */
static void render_shrunk_batch(sl_occ_raster *r, const sl_occ_view *v, uint32_t n)
{
    if (!n)
        return;
    const float *to_clip = v->ortho ? g_shrunk_ortho : g_shrunk_persp;
    (void)sl_raster_render_triangles(r->ctx, r->shrunk, 3 * n, r->shrunk_idx, n, 12, to_clip, SL_RASTER_CULL_NONE,
                                     NULL);
    if (r->rec)
        sl_occ_recorder_batch(r->rec, r->shrunk, 12, r->shrunk_idx, n, to_clip, SL_RASTER_CULL_NONE);
}

/* res=any with inner=faces: a prism by inner coverage. Each convex face (wall, roof or floor piece, sl_occ_face) is
 * projected in double, eroded on screen by the pixel footprint (every edge moved inward by
 * (|nx| + |ny|) / 2, the reach of a pixel square's corners along its unit normal n, plus
 * SL_OCC_MIN_INSET_PX for both snappings), and drawn with its depth plane moved farther by the
 * plane's change over half a pixel ((|dx| + |dy|) / 2 of its screen gradient), nudged by
 * SL_MARGIN_REL: a pixel centre the rasterizer covers then has its whole square inside the face,
 * and the depth written there is no nearer than the face anywhere in that square. So every sample
 * of every resolution that falls in a covered pixel sees the prism's face (inside its building)
 * no nearer than the buffer says. Faces are drawn on their own (each a fan of its eroded polygon,
 * both sides: a back face is a face of the solid too, farther than the front one), so edges
 * between faces leave cracks a pixel wide; a face that erodes away, or with a vertex not between
 * the near and far planes, is dropped (fewer occluders is safe). */
void sl_occ_render_prism_eroded(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const sl_occ_proxy *pr)
{
    const double W = (double)v->width, H = (double)v->height, eps = SL_OCC_MIN_INSET_PX;
    double m[16];
    for (int i = 0; i < 16; i++)
        m[i] = v->vp.m[i];
    sl_occ_screen_vertex *proj = r->shrunk_proj;
    uint32_t n = 0;
    for (uint32_t fi = 0; fi < pr->face_count; fi++) {
        const sl_occ_face *f = &s->faces[pr->face_first + fi];
        uint32_t c = f->count;
        if (c < 3 || c > r->shrunk_proj_cap || n + (c - 2) > r->shrunk_cap)
            continue;
        bool ok = true;
        for (uint32_t i = 0; i < c && ok; i++) {
            proj[i] = project_vertex(v, m, &s->face_verts[f->first + i].x);
            ok = proj[i].ok && proj[i].between && proj[i].d > 0;
        }
        if (!ok)
            continue;
        /* orientation and the depth plane d = d0 + gx x + gy y through the largest fan triangle */
        double area = 0, best = 0;
        uint32_t bi = 1;
        for (uint32_t i = 1; i + 1 < c; i++) {
            double t = (proj[i].x - proj[0].x) * (proj[i + 1].y - proj[0].y) -
                       (proj[i].y - proj[0].y) * (proj[i + 1].x - proj[0].x);
            area += t;
            if (fabs(t) > fabs(best))
                best = t, bi = i;
        }
        if (!(fabs(area) > 1e-9) || !(fabs(best) > 0))
            continue;
        const sl_occ_screen_vertex *A = &proj[0], *B = &proj[bi], *C = &proj[bi + 1];
        double ux = B->x - A->x, uy = B->y - A->y, wx = C->x - A->x, wy = C->y - A->y;
        double du = (double)B->d - A->d, dw = (double)C->d - A->d;
        double gx = (du * wy - dw * uy) / best, gy = (dw * ux - du * wx) / best;
        double d0 = (double)A->d - gx * A->x - gy * A->y;
        double drop = 0.5 * (fabs(gx) + fabs(gy));
        /* eroded polygon: offset lines of consecutive edges intersected (interior on the left of
         * each edge when area > 0) */
        double ex[64], ey[64], nxs[64], nys[64], off[64];
        if (c > 64)
            continue;
        double sgn = area > 0 ? 1.0 : -1.0;
        for (uint32_t i = 0; i < c && ok; i++) {
            const sl_occ_screen_vertex *p = &proj[i], *q = &proj[(i + 1) % c];
            double dx = q->x - p->x, dy = q->y - p->y, len = sqrt(dx * dx + dy * dy);
            if (!(len > 1e-12)) {
                ok = false;
                break;
            }
            nxs[i] = -sgn * dy / len;
            nys[i] = sgn * dx / len;
            off[i] = nxs[i] * p->x + nys[i] * p->y + 0.5 * (fabs(nxs[i]) + fabs(nys[i])) + eps;
        }
        for (uint32_t i = 0; i < c && ok; i++) {
            uint32_t a = (i + c - 1) % c, b = i;
            double det = nxs[a] * nys[b] - nys[a] * nxs[b];
            if (!(fabs(det) > 1e-9)) {
                ok = false;
                break;
            }
            ex[i] = (off[a] * nys[b] - nys[a] * off[b]) / det;
            ey[i] = (nxs[a] * off[b] - off[a] * nxs[b]) / det;
        }
        /* every eroded vertex inside every offset line, or the face eroded away */
        for (uint32_t i = 0; i < c && ok; i++)
            for (uint32_t k = 0; k < c && ok; k++)
                ok = nxs[k] * ex[i] + nys[k] * ey[i] >= off[k] - 1e-9 * (1.0 + fabs(off[k]));
        if (!ok)
            continue;
        float *o = r->shrunk + 9 * (size_t)n;
        float vx[64][3];
        for (uint32_t i = 0; i < c && ok; i++) {
            double d = (d0 + gx * ex[i] + gy * ey[i] - drop);
            d -= fabs(d) * SL_MARGIN_REL;
            if (!(d > 0) || !isfinite(d)) {
                ok = false;
                break;
            }
            double nx = 2.0 * ex[i] / W - 1.0, ny = 1.0 - 2.0 * ey[i] / H;
            double w = v->ortho ? 1.0 : 1.0 / d;
            vx[i][0] = (float)(nx * w);
            vx[i][1] = (float)(ny * w);
            vx[i][2] = v->ortho ? (float)(1.0 - 2.0 * d) : (float)w;
        }
        if (!ok)
            continue;
        for (uint32_t i = 1; i + 1 < c; i++) {
            memcpy(o, vx[0], sizeof vx[0]);
            memcpy(o + 3, vx[i], sizeof vx[0]);
            memcpy(o + 6, vx[i + 1], sizeof vx[0]);
            o += 9;
            n++;
        }
    }
    render_shrunk_batch(r, v, n);
}

/* res=any, the default (inner=hull): a prism by the inner coverage of its silhouette, not of each
 * face. The prism is cut into convex prisms, one per convex roof piece (a convex footprint is one).
 * A convex prism's screen silhouette is the convex hull H of its projected vertices, and the depth
 * of its surface on a pixel ray is D(p) = min_k L_k(p) over its front faces' depth planes L_k
 * (larger = nearer: the ray enters the solid through the last front plane it crosses). A pixel
 * square S centred at c inside H eroded by the square (every hull edge moved inward by
 * (|nx| + |ny|) / 2, plus SL_OCC_MIN_INSET_PX for both snappings) sees the prism at every sample,
 * no nearer than E(c) = min_k (L_k(c) - (1/2 + SL_OCC_MIN_INSET_PX) (|gx_k| + |gy_k|)), the least
 * of each plane over the square (grown by the margin): E(c) <= min over S of D. E is concave (a
 * minimum of affine functions), so a triangle whose vertices carry E's values lies below E
 * everywhere in it: each front face, clipped to the eroded hull, is drawn as a fan with E at its
 * vertices. Only the hull's edges are eroded, so a building corner and the edges between a roof
 * and its walls leave no crack; the creases of E follow the face edges. A face nearly edge-on
 * (its projection under half a square pixel: its plane is ill-conditioned on screen) enters E as
 * the constant of its farthest vertex instead (its surface is nowhere farther; where it is the
 * front surface, D is at least that), and is not drawn. Planes come from the vertices projected
 * in double (sl_occ_screen_vertex keeps x, y; the depth is recomputed in double here). A convex
 * piece with a vertex not between the near and far planes is dropped (fewer occluders is safe). */
typedef struct hull_vertex {
    double x, y, d;
} hull_vertex;

static bool hull_project(const sl_occ_view *v, const double m[16], sl_vec3 p, hull_vertex *o)
{
    double cl[4];
    for (int r = 0; r < 4; r++)
        cl[r] = m[r] * p.x + m[4 + r] * p.y + m[8 + r] * p.z + m[12 + r];
    if (!(cl[3] > 1e-5) || !isfinite(cl[0]) || !isfinite(cl[1]) || !isfinite(cl[2]) || !(cl[2] >= -cl[3]) ||
        !(cl[2] <= cl[3]))
        return false;
    double inv = 1.0 / cl[3];
    o->x = (cl[0] * inv + 1.0) * 0.5 * (double)v->width;
    o->y = (1.0 - cl[1] * inv) * 0.5 * (double)v->height;
    o->d = v->ortho ? 0.5 * (1.0 - cl[2] * inv) : inv;
    return o->d > 0;
}

static inline double cross_h(const hull_vertex *o, const hull_vertex *a, const hull_vertex *b)
{
    return (a->x - o->x) * (b->y - o->y) - (a->y - o->y) * (b->x - o->x);
}


#define HULL_MAX_PIECE 64   /* vertices of a convex roof piece drawn this way (larger: dropped) */
#define HULL_MAX_V 128      /* vertices of a convex solid drawn by hull_draw */
#define HULL_MAX_F 256      /* its faces */
#define HULL_MAX_FACE_V 64  /* a face's vertices */

/* Draw a convex solid by its silhouette (see above): pv its nv projected vertices, its nf faces as
 * index lists (fidx from fstart[k], flen[k] vertices each, any winding) with front[k] when the face
 * may face the eye (a face that may be front must be: a missing front plane would make the depths
 * too near). grow: pixels the hull is eroded by besides the pixel square and SL_OCC_MIN_INSET_PX
 * (a solid convex only within a tolerance). Appends to r->shrunk from triangle n (flushing when
 * full); returns the new count. */
static uint32_t hull_draw(sl_occ_raster *r, const sl_occ_view *v, const hull_vertex *pv, uint32_t nv,
                          const uint32_t *fidx, const uint32_t *fstart, const uint32_t *flen, uint32_t nf,
                          const bool *front, double grow, uint32_t n)
{
    const double W = (double)v->width, H = (double)v->height, eps = SL_OCC_MIN_INSET_PX;
    if (nv < 3 || nv > HULL_MAX_V || nf > HULL_MAX_F)
        return n;
    /* the convex hull of the projected vertices (monotone chain), counter-clockwise in screen
     * coordinates (x right, y down: interior on the left of each edge with cross > 0) */
    hull_vertex sorted[HULL_MAX_V], hull[2 * HULL_MAX_V + 2];
    memcpy(sorted, pv, nv * sizeof *pv);
    for (uint32_t i = 1; i < nv; i++) {
        hull_vertex x = sorted[i];
        uint32_t j = i;
        for (; j > 0 && (sorted[j - 1].x > x.x || (sorted[j - 1].x == x.x && sorted[j - 1].y > x.y)); j--)
            sorted[j] = sorted[j - 1];
        sorted[j] = x;
    }
    uint32_t h = 0;
    for (uint32_t i = 0; i < nv; i++) {
        while (h >= 2 && cross_h(&hull[h - 2], &hull[h - 1], &sorted[i]) <= 0)
            h--;
        hull[h++] = sorted[i];
    }
    for (uint32_t i = nv - 1, lo = h + 1; i-- > 0;) {
        while (h >= lo && cross_h(&hull[h - 2], &hull[h - 1], &sorted[i]) <= 0)
            h--;
        hull[h++] = sorted[i];
    }
    h--; /* the last point repeats the first */
    if (h < 3)
        return n;
    /* the eroded hull: half-planes nx x + ny y >= off (inward unit normals) */
    double hnx[2 * HULL_MAX_V], hny[2 * HULL_MAX_V], hoff[2 * HULL_MAX_V];
    for (uint32_t i = 0; i < h; i++) {
        const hull_vertex *p = &hull[i], *q = &hull[(i + 1) % h];
        double dx = q->x - p->x, dy = q->y - p->y, len = sqrt(dx * dx + dy * dy);
        if (!(len > 1e-12) || !isfinite(len))
            return n;
        hnx[i] = -dy / len;
        hny[i] = dx / len;
        hoff[i] = hnx[i] * p->x + hny[i] * p->y + 0.5 * (fabs(hnx[i]) + fabs(hny[i])) + eps + grow;
    }
    /* the front faces' depth planes, less their change over the pixel square grown by eps */
    double gx[HULL_MAX_F], gy[HULL_MAX_F], g0[HULL_MAX_F], cst[HULL_MAX_F];
    int kind[HULL_MAX_F]; /* 0 back, 1 front plane (drawn), 2 front nearly edge-on (constant) */
    for (uint32_t k = 0; k < nf; k++) {
        const uint32_t *ix = fidx + fstart[k];
        kind[k] = front[k] && flen[k] >= 3 && flen[k] <= HULL_MAX_FACE_V ? 1 : 0;
        if (!kind[k]) {
            if (front[k])
                return n; /* a front face this cannot handle: draw nothing */
            continue;
        }
        double best = 0, dmin = INFINITY;
        uint32_t bi = 1;
        for (uint32_t i = 1; i + 1 < flen[k]; i++) {
            double t = cross_h(&pv[ix[0]], &pv[ix[i]], &pv[ix[i + 1]]);
            if (fabs(t) > fabs(best))
                best = t, bi = i;
        }
        for (uint32_t i = 0; i < flen[k]; i++)
            dmin = pv[ix[i]].d < dmin ? pv[ix[i]].d : dmin;
        cst[k] = dmin;
        if (!(fabs(best) >= 1.0)) {
            kind[k] = 2;
            continue;
        }
        const hull_vertex *A = &pv[ix[0]], *B = &pv[ix[bi]], *C = &pv[ix[bi + 1]];
        double ux = B->x - A->x, uy = B->y - A->y, wx = C->x - A->x, wy = C->y - A->y;
        double du = B->d - A->d, dw = C->d - A->d;
        gx[k] = (du * wy - dw * uy) / best;
        gy[k] = (dw * ux - du * wx) / best;
        g0[k] = A->d - gx[k] * A->x - gy[k] * A->y - (0.5 + eps) * (fabs(gx[k]) + fabs(gy[k]));
        if (!isfinite(g0[k]) || !isfinite(gx[k]) || !isfinite(gy[k]))
            kind[k] = 2;
    }
    for (uint32_t k = 0; k < nf; k++) {
        if (kind[k] != 1)
            continue;
        const uint32_t *ix = fidx + fstart[k];
        /* the face's projection clipped to the eroded hull */
        enum { CAP = HULL_MAX_FACE_V + 2 * HULL_MAX_V + 4 };
        double ax[2][CAP], ay[2][CAP];
        uint32_t len = flen[k], cur = 0;
        for (uint32_t i = 0; i < len; i++) {
            ax[0][i] = pv[ix[i]].x;
            ay[0][i] = pv[ix[i]].y;
        }
        for (uint32_t e = 0; e < h && len >= 3; e++) {
            len = sl_clip_half(ax[cur], ay[cur], len, hnx[e], hny[e], hoff[e], ax[cur ^ 1], ay[cur ^ 1], CAP);
            cur ^= 1;
        }
        if (len < 3 || len - 2 > r->shrunk_cap)
            continue;
        if (n + (len - 2) > r->shrunk_cap) {
            render_shrunk_batch(r, v, n);
            n = 0;
        }
        float vx[CAP][3];
        bool ok = true;
        for (uint32_t i = 0; i < len && ok; i++) {
            double x = ax[cur][i], y = ay[cur][i], e = INFINITY;
            for (uint32_t q = 0; q < nf; q++) {
                double t = kind[q] == 1 ? g0[q] + gx[q] * x + gy[q] * y : kind[q] == 2 ? cst[q] : INFINITY;
                e = t < e ? t : e;
            }
            e -= fabs(e) * SL_MARGIN_REL;
            if (!(e > 0) || !isfinite(e)) {
                ok = false;
                break;
            }
            double nx = 2.0 * x / W - 1.0, ny = 1.0 - 2.0 * y / H;
            double w = v->ortho ? 1.0 : 1.0 / e;
            vx[i][0] = (float)(nx * w);
            vx[i][1] = (float)(ny * w);
            vx[i][2] = v->ortho ? (float)(1.0 - 2.0 * e) : (float)w;
        }
        if (!ok)
            continue;
        float *o = r->shrunk + 9 * (size_t)n;
        for (uint32_t i = 1; i + 1 < len; i++) {
            memcpy(o, vx[0], sizeof vx[0]);
            memcpy(o + 3, vx[i], sizeof vx[0]);
            memcpy(o + 6, vx[i + 1], sizeof vx[0]);
            o += 9;
            n++;
        }
    }
    return n;
}

/* Does the face with outward normal nrm through p0 face the eye (orthographic: the view
 * direction), with a tolerance so that a face nearly edge-on counts as front? */
static bool hull_facing(const sl_occ_view *v, const double *nrm, const double *p0)
{
    double ex = v->ortho ? -(double)v->fwd.x : (double)v->eye.x - p0[0];
    double ey = v->ortho ? -(double)v->fwd.y : (double)v->eye.y - p0[1];
    double ez = v->ortho ? -(double)v->fwd.z : (double)v->eye.z - p0[2];
    double nl = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    double el = sqrt(ex * ex + ey * ey + ez * ez);
    return nrm[0] * ex + nrm[1] * ey + nrm[2] * ez > -1e-6 * nl * el;
}

void sl_occ_render_prism_hull(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const sl_occ_proxy *pr)
{
    double m[16];
    for (int i = 0; i < 16; i++)
        m[i] = v->vp.m[i];
    const double zb = pr->box.min.z;
    uint32_t n = 0;
    for (uint32_t fi = 0; fi < pr->face_count; fi++) {
        const sl_occ_face *f = &s->faces[pr->face_first + fi];
        if (!(f->normal.z > 0.5f) || f->count < 3 || f->count > HULL_MAX_PIECE)
            continue; /* a convex roof piece stands for its convex prism */
        const uint32_t c = f->count;
        const sl_vec3 *top = &s->face_verts[f->first];
        hull_vertex pv[2 * HULL_MAX_PIECE]; /* top ring, then bottom ring */
        bool ok = true;
        for (uint32_t i = 0; i < c && ok; i++)
            ok = hull_project(v, m, top[i], &pv[i]) &&
                 hull_project(v, m, (sl_vec3){top[i].x, top[i].y, (float)zb}, &pv[c + i]);
        if (!ok)
            continue;
        /* faces: 0 the roof piece, 1 the floor piece, 2 + i the wall on edge i -> i + 1 */
        uint32_t fidx[2 * HULL_MAX_PIECE + 4 * HULL_MAX_PIECE], fstart[HULL_MAX_PIECE + 2], flen[HULL_MAX_PIECE + 2];
        bool front[HULL_MAX_PIECE + 2];
        uint32_t k = 0;
        for (uint32_t face = 0; face < c + 2; face++) {
            fstart[face] = k;
            double nrm[3], p0[3] = {top[0].x, top[0].y, top[0].z};
            if (face < 2) {
                for (uint32_t i = 0; i < c; i++)
                    fidx[k++] = face == 0 ? i : c + (c - 1 - i);
                flen[face] = c;
                nrm[0] = nrm[1] = 0, nrm[2] = face == 0 ? 1 : -1;
                p0[2] = face == 0 ? top[0].z : zb;
            } else {
                uint32_t i = face - 2, j = (i + 1) % c;
                fidx[k++] = c + i, fidx[k++] = c + j, fidx[k++] = j, fidx[k++] = i;
                flen[face] = 4;
                nrm[0] = (double)top[j].y - top[i].y, nrm[1] = (double)top[i].x - top[j].x, nrm[2] = 0;
                p0[0] = top[i].x, p0[1] = top[i].y;
            }
            front[face] = hull_facing(v, nrm, p0);
        }
        n = hull_draw(r, v, pv, 2 * c, fidx, fstart, flen, c + 2, front, 0.0, n);
    }
    render_shrunk_batch(r, v, n);
}

/* res=any, inner=hull: a MESH or SCENE_MESH proxy by its convex parts (convex_parts.h), each
 * drawn by its silhouette as a convex prism piece is (hull_draw), its front planes those of its
 * triangles facing the eye; the erosion grows by the part's convexity tolerance on screen. A part with a vertex not between the near and far planes, an open part whose
 * hole may face the eye, every part of an orthographic view, and the triangles in no part are
 * drawn one by one, shrunk (sl_occ_render_mesh_shrunk). */
void sl_occ_render_mesh_hull(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, uint32_t mesh, sl_affine xf)
{
    const sl_occ_cparts *cp = s->cparts ? &s->cparts[mesh] : NULL;
    if (!cp || !cp->built || v->ortho) {
        sl_occ_render_mesh_shrunk(r, s->scene, v, mesh, xf, NULL, 0);
        return;
    }
    double m[16];
    mul_affine_d(&v->vp, &xf, m);
    /* a bound of the transform's stretch (Frobenius norm of its linear part) */
    double sc2 = 0;
    for (int row = 0; row < 3; row++)
        for (int col = 0; col < 3; col++)
            sc2 += (double)xf.m[4 * row + col] * xf.m[4 * row + col];
    const double stretch = sqrt(sc2);
    uint32_t n = 0;
    for (uint32_t pi = 0; pi < cp->part_count; pi++) {
        const sl_occ_cpart *p = &cp->parts[pi];
        hull_vertex pv[SL_OCC_CPART_MAX_VERTS];
        double wv[SL_OCC_CPART_MAX_VERTS][3];
        bool ok = p->vcount <= HULL_MAX_V && p->tcount <= HULL_MAX_F;
        double dmax = 0;
        for (uint32_t i = 0; i < p->vcount && ok; i++) {
            const float *q = cp->pos + 3 * (size_t)(p->vfirst + i);
            ok = hull_project(v, m, (sl_vec3){q[0], q[1], q[2]}, &pv[i]);
            for (int row = 0; row < 3; row++)
                wv[i][row] = (double)xf.m[4 * row] * q[0] + (double)xf.m[4 * row + 1] * q[1] +
                             (double)xf.m[4 * row + 2] * q[2] + xf.m[4 * row + 3];
            dmax = pv[i].d > dmax ? pv[i].d : dmax;
        }
        for (uint32_t hi = 0; ok && hi < p->holes; hi++) {
            const double *a = wv[p->hole_v[hi][0]], *b = wv[p->hole_v[hi][1]], *c = wv[p->hole_v[hi][2]];
            double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
            double nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
            ok = !hull_facing(v, nrm, a); /* a ray through a hole facing the eye meets no front face */
        }
        if (!ok || !(dmax > 0)) {
            render_shrunk_batch(r, v, n);
            n = 0;
            sl_occ_render_mesh_shrunk(r, s->scene, v, mesh, xf, cp->src + p->tfirst, p->tcount);
            continue;
        }
        uint32_t fidx[3 * HULL_MAX_F], fstart[HULL_MAX_F], flen[HULL_MAX_F];
        bool front[HULL_MAX_F];
        for (uint32_t t = 0; t < p->tcount; t++) {
            const uint32_t *tri = cp->tri + 3 * (size_t)(p->tfirst + t);
            fstart[t] = 3 * t;
            flen[t] = 3;
            memcpy(fidx + 3 * t, tri, 3 * sizeof(uint32_t));
            const double *a = wv[tri[0]], *b = wv[tri[1]], *c = wv[tri[2]];
            double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
            double nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
            front[t] = hull_facing(v, nrm, a);
        }
        /* the depths need no allowance: the first triangle a ray meets faces the eye, so its plane
         * is among the front planes, convex or not; the silhouette may lie inside the hull by the
         * part's convexity tolerance (dev * stretch metres at forward distance 1 / dmax at least):
         * the hull is eroded by twice that on screen */
        double grow = 2.0 * p->dev * stretch * (double)v->focal_max * dmax;
        n = hull_draw(r, v, pv, p->vcount, fidx, fstart, flen, p->tcount, front, grow, n);
    }
    render_shrunk_batch(r, v, n);
    if (cp->rest_count)
        sl_occ_render_mesh_shrunk(r, s->scene, v, mesh, xf, cp->rest, cp->rest_count);
}


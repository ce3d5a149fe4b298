/* frusta: object-space shadow frusta, after Hudson, Manocha, Cohen, Lin, Hoff & Zhang,
 * "Accelerated Occlusion Culling using Shadow Frusta" (SoCG 1997), as summarised in the SIGGRAPH
 * 2000 course "Visibility, problems, techniques and applications" (section 5.2).
 *
 * Per frame:
 *  1. choose occluders: the best proxies in the frustum by Coorg-Teller quality (occlusion/select.c;
 *     Hudson et al. precompute candidates per viewpoint cell, here the quality walk over the BVH
 *     plays that role every frame), then their planar convex faces (prism walls, convex pieces of
 *     roofs, the largest triangles of mesh proxies) ranked by the same quality per face; the best
 *     `frusta` faces become occluders;
 *  2. for each face, its shadow frustum: the planes through the eye and each edge (for an
 *     orthographic camera, through each edge along the view direction) and the face's own plane,
 *     keeping the side away from the eye;
 *  3. traverse the object BVH; a node or object box is culled when it lies inside a single shadow
 *     frustum (no occluder fusion, as in the paper), tested with the n-vertex of each plane.
 * Conservative and exact in object space: a box inside a shadow frustum is hidden behind a face
 * that lies inside a solid object (or is an occluder's own triangle). Side planes are tightened
 * by SL_OCC_MIN_INSET_PX pixels' worth of angle so that a pixel centre the oracle could see past
 * the face's edge (snapping) never counts as shadowed; the face plane by a relative 1e-6. */
#include "cull/occlusion/base.h"
#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/view.h"
#include "cull/occlusion/walk.h"

#include <math.h>

#define MAX_FACE_VERTS 16

typedef struct frusta_config {
    sl_occ_common c;
    uint32_t frusta;
} frusta_config;

typedef struct shadow {
    uint32_t count;             /* planes: count side planes then the face plane */
    int32_t x0, y0, x1, y1;     /* screen rectangle of the face: a box in the shadow projects inside it */
    /* a face clipped to the near plane has up to MAX_FACE_VERTS + 1 sides, then the face plane */
    float px[MAX_FACE_VERTS + 2], py[MAX_FACE_VERTS + 2], pz[MAX_FACE_VERTS + 2], pd[MAX_FACE_VERTS + 2];
    float margin[MAX_FACE_VERTS + 2]; /* side planes: metres per metre of distance (perspective) or metres */
} shadow;

typedef struct face_pick {
    uint32_t face;
    float quality;
} face_pick;

typedef struct frusta_state {
    sl_occ_base b;              /* BVH, proxies, selection buffers */
    frusta_config cfg;
    face_pick *faces;           /* candidate faces of the frame */
    uint32_t face_cap;
    shadow *sh;
} frusta_state;

static const char g_help[] =
    "frusta=1..1024 (default 48): most shadow frusta (occluding faces) per frame\n"
    "occluders=0..4096 (default 24): proxies whose faces compete to become shadow frusta\n"
    "budget=0..10000000 (default 10000000): triangle budget of those proxies\n"
    "min_quality=NUMBER (default 0.0005): least quality (solid angle, sr) of a proxy\n"
    "inset=0.01..10 (default 0.1): metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n"
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n";

static sl_status frusta_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    frusta_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_opts_u32(o, "frusta", 48, 1, 1024, &c->frusta, err)) != SL_OK ||
        (st = sl_occ_configure_common(o, SL_OCC_OPT_SELECT, 24, 10000000, &c->c, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void frusta_destroy(void *state)
{
    frusta_state *s = state;
    if (!s)
        return;
    sl_allocator a = s->b.alloc;
    sl_free(&a, s->faces, (size_t)(s->face_cap ? s->face_cap : 1) * sizeof(face_pick));
    sl_free(&a, s->sh, (size_t)s->cfg.frusta * sizeof(shadow));
    sl_occ_base_free(&s->b);
    sl_free(&a, s, sizeof *s);
}

static sl_status frusta_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                               const sl_allocator *alloc, void **state, sl_error *err)
{
    frusta_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "frusta: out of memory");
    s->cfg = *(const frusta_config *)config;
    sl_status st = sl_occ_base_init(&s->b, scene, "frusta", &s->cfg.c, true, 16, true, extras, alloc, err);
    if (st != SL_OK) {
        sl_free(alloc, s, sizeof *s);
        return st;
    }
    /* the faces of the chosen proxies: at most the largest face count of a proxy, times the picks */
    const sl_occ_set *o = s->b.occ;
    uint32_t maxf = 1;
    for (uint32_t p = 0; p < o->proxy_count; p++)
        maxf = SL_MAX(maxf, o->proxies[p].face_count);
    s->face_cap = (uint32_t)SL_MIN((uint64_t)maxf * s->b.pick_cap, (uint64_t)o->face_count + 1);
    s->faces = sl_alloc(alloc, (size_t)s->face_cap * sizeof(face_pick));
    s->sh = sl_alloc(alloc, (size_t)s->cfg.frusta * sizeof(shadow));
    if (!s->faces || !s->sh) {
        frusta_destroy(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "frusta: out of memory");
    }
    *state = s;
    return SL_OK;
}

static sl_status frusta_scene_changed(void *state, sl_error *err)
{
    frusta_state *s = state;
    return sl_occ_base_scene_changed(&s->b, err);
}

/* Coorg-Teller quality of one face (positive when it faces the eye). */
static float face_quality(const sl_occ_face *f, const sl_occ_view *v)
{
    if (v->ortho) {
        float ndv = f->normal.x * v->fwd.x + f->normal.y * v->fwd.y + f->normal.z * v->fwd.z;
        return ndv < 0 ? -f->area * ndv : 0; /* no distance falloff in a parallel view */
    }
    float dx = f->centre.x - v->eye.x, dy = f->centre.y - v->eye.y, dz = f->centre.z - v->eye.z;
    float d2 = dx * dx + dy * dy + dz * dz;
    if (!(d2 > 1e-6f))
        return 0;
    float ndv = (f->normal.x * dx + f->normal.y * dy + f->normal.z * dz) / sqrtf(d2);
    return ndv < 0 ? -f->area * ndv / d2 : 0;
}

/* Clip a face to the part beyond the near plane, in double precision: the plane is the one the
 * renderer and the oracle clip at, z_clip + w_clip = 0 of the view's float world-to-clip matrix,
 * moved 1e-6 of the terms' magnitude plus 2e-5 of the near distance farther (the oracle clips
 * the same float matrix in double: the margin covers the float face vertices and the rounding of
 * the interpolation). Sutherland-Hodgman; a convex polygon gains at most one vertex. Returns the
 * count left (0: the whole face is nearer than the near plane). */
static uint32_t clip_near(const sl_occ_view *v, const sl_vec3 *p, uint32_t n, double (*q)[3])
{
    const float *M = v->vp.m;
    double P[4];
    for (int c = 0; c < 4; c++)
        P[c] = (double)M[4 * c + 2] + (double)M[4 * c + 3];
    double dist[MAX_FACE_VERTS], scale = 0;
    for (uint32_t i = 0; i < n; i++) {
        dist[i] = P[0] * p[i].x + P[1] * p[i].y + P[2] * p[i].z + P[3];
        scale = fmax(scale, fabs(P[0] * p[i].x) + fabs(P[1] * p[i].y) + fabs(P[2] * p[i].z) + fabs(P[3]));
    }
    double gl = sqrt(P[0] * P[0] + P[1] * P[1] + P[2] * P[2]);
    double tau = 1e-6 * scale + 2e-5 * v->view.near_plane * gl;
    uint32_t m = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        double da = dist[i] - tau, db = dist[j] - tau;
        /* rounding on a near-degenerate face could add more than one vertex: drop the face then */
        if (da >= 0) {
            if (m == MAX_FACE_VERTS + 1)
                return 0;
            q[m][0] = p[i].x, q[m][1] = p[i].y, q[m][2] = p[i].z;
            m++;
        }
        if ((da >= 0) != (db >= 0)) {
            if (m == MAX_FACE_VERTS + 1)
                return 0;
            double t = da / (da - db);
            q[m][0] = p[i].x + t * ((double)p[j].x - p[i].x);
            q[m][1] = p[i].y + t * ((double)p[j].y - p[i].y);
            q[m][2] = p[i].z + t * ((double)p[j].z - p[i].z);
            m++;
        }
    }
    return m;
}

/* Build the shadow frustum of a face; false when degenerate (the eye in its plane, a sliver) or
 * when nothing of it lies beyond the near plane. Only the part of the face beyond the near plane
 * occludes: the renderer (and the oracle) clip the rest away and see through the hole, so the
 * frustum is built from the clipped polygon (issue 12: an eye a few centimetres from a wall). */
static bool make_shadow(const sl_occ_set *o, const sl_occ_face *f, const sl_occ_view *v, shadow *sh)
{
    if (f->count < 3 || f->count > MAX_FACE_VERTS)
        return false;
    double p[MAX_FACE_VERTS + 1][3];
    uint32_t n = clip_near(v, o->face_verts + f->first, f->count, p);
    if (n < 3)
        return false;
    const sl_vec3 *fp = o->face_verts + f->first;
    double E[3] = {v->eye.x, v->eye.y, v->eye.z}, F[3] = {v->fwd.x, v->fwd.y, v->fwd.z};
    double N[3] = {f->normal.x, f->normal.y, f->normal.z};
    /* the clipped polygon's centroid: inside it (convex), so inside every side plane */
    double C[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            C[k] += p[i][k] / (double)n;
    double scale = fabs(C[0]) + fabs(C[1]) + fabs(C[2]) + 1.0;
    /* the face plane, inside = the side away from the eye (or along the view direction) */
    double nd = -(N[0] * fp[0].x + N[1] * fp[0].y + N[2] * fp[0].z);
    double side = v->ortho ? -(N[0] * F[0] + N[1] * F[1] + N[2] * F[2]) : N[0] * E[0] + N[1] * E[1] + N[2] * E[2] + nd;
    if (fabs(side) < (v->ortho ? 1e-4 : 1e-4 * scale))
        return false;
    double s = side > 0 ? -1.0 : 1.0;
    /* angle (perspective) or distance (orthographic) a box must keep inside each side plane */
    double m = SL_OCC_MIN_INSET_PX / (double)v->focal;
    for (uint32_t i = 0; i < n; i++) {
        const double *a = p[i], *b = p[(i + 1) % n];
        double nx, ny, nz, d;
        if (v->ortho) {
            double e[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
            nx = e[1] * F[2] - e[2] * F[1];
            ny = e[2] * F[0] - e[0] * F[2];
            nz = e[0] * F[1] - e[1] * F[0];
            d = -(nx * a[0] + ny * a[1] + nz * a[2]);
        } else {
            double u[3] = {a[0] - E[0], a[1] - E[1], a[2] - E[2]}, w[3] = {b[0] - E[0], b[1] - E[1], b[2] - E[2]};
            nx = u[1] * w[2] - u[2] * w[1];
            ny = u[2] * w[0] - u[0] * w[2];
            nz = u[0] * w[1] - u[1] * w[0];
            d = -(nx * E[0] + ny * E[1] + nz * E[2]);
        }
        double len = sqrt(nx * nx + ny * ny + nz * nz);
        if (!(len > 1e-12))
            return false;
        nx /= len, ny /= len, nz /= len, d /= len;
        /* inward: the polygon's centroid is inside */
        double c = nx * C[0] + ny * C[1] + nz * C[2] + d;
        if (fabs(c) < 1e-9 * scale)
            return false;
        if (c < 0)
            nx = -nx, ny = -ny, nz = -nz, d = -d;
        sh->px[i] = (float)nx;
        sh->py[i] = (float)ny;
        sh->pz[i] = (float)nz;
        sh->pd[i] = (float)d;
        sh->margin[i] = (float)m;
    }
    sh->px[n] = (float)(s * N[0]);
    sh->py[n] = (float)(s * N[1]);
    sh->pz[n] = (float)(s * N[2]);
    sh->pd[n] = (float)(s * nd);
    sh->margin[n] = 0;
    sh->count = n;
    /* the face's screen rectangle, grown by a pixel: the rectangle of a box inside the frustum lies
     * inside it (a face reaching behind the eye covers the whole screen) */
    const float *M = v->vp.m;
    float hw = 0.5f * (float)v->width, hh = 0.5f * (float)v->height;
    float minx = INFINITY, maxx = -INFINITY, miny = INFINITY, maxy = -INFINITY;
    bool whole = false;
    for (uint32_t i = 0; i < n && !whole; i++) {
        float px = (float)p[i][0], py = (float)p[i][1], pz = (float)p[i][2];
        float x = M[0] * px + M[4] * py + M[8] * pz + M[12];
        float y = M[1] * px + M[5] * py + M[9] * pz + M[13];
        float w = M[3] * px + M[7] * py + M[11] * pz + M[15];
        if (!(w > 1e-5f)) {
            whole = true;
            break;
        }
        float sx = x / w * hw + hw, sy = hh - y / w * hh;
        minx = sl_occ_minf(minx, sx), maxx = sl_occ_maxf(maxx, sx);
        miny = sl_occ_minf(miny, sy), maxy = sl_occ_maxf(maxy, sy);
    }
    if (whole || !isfinite(minx) || !isfinite(maxx) || !isfinite(miny) || !isfinite(maxy)) {
        sh->x0 = sh->y0 = INT32_MIN;
        sh->x1 = sh->y1 = INT32_MAX;
    } else {
        sh->x0 = (int32_t)sl_occ_maxf(floorf(minx) - 1.0f, -1e9f);
        sh->y0 = (int32_t)sl_occ_maxf(floorf(miny) - 1.0f, -1e9f);
        sh->x1 = (int32_t)sl_occ_minf(ceilf(maxx) + 1.0f, 1e9f);
        sh->y1 = (int32_t)sl_occ_minf(ceilf(maxy) + 1.0f, 1e9f);
    }
    return true;
}

/* Is box b wholly inside the shadow frustum? Each plane's n-vertex (the corner least inside) must
 * be inside by the margin; side planes of a perspective frustum scale it by the farthest corner's
 * distance from the eye, a bound of every corner's. Plane rounding is covered by a relative 1e-6. */
static bool in_shadow(const shadow *sh, const sl_aabb *b, const sl_occ_view *v, float rmax)
{
    for (uint32_t i = 0; i <= sh->count; i++) {
        float a = sh->px[i], bb = sh->py[i], c = sh->pz[i];
        float nx = a >= 0 ? b->min.x : b->max.x, ny = bb >= 0 ? b->min.y : b->max.y, nz = c >= 0 ? b->min.z : b->max.z;
        float val = a * nx + bb * ny + c * nz + sh->pd[i];
        float slack = SL_MARGIN_SHADOW_REL * (fabsf(a * nx) + fabsf(bb * ny) + fabsf(c * nz) + fabsf(sh->pd[i]));
        float need = i < sh->count ? sh->margin[i] * (v->ortho ? 1.0f : rmax) : 0.0f;
        if (!(val > need + slack))
            return false;
    }
    return true;
}

/* Farthest distance from the eye to a corner of b. */
static float far_dist(const sl_occ_view *v, const sl_aabb *b)
{
    float dx = sl_occ_maxf(fabsf(b->min.x - v->eye.x), fabsf(b->max.x - v->eye.x));
    float dy = sl_occ_maxf(fabsf(b->min.y - v->eye.y), fabsf(b->max.y - v->eye.y));
    float dz = sl_occ_maxf(fabsf(b->min.z - v->eye.z), fabsf(b->max.z - v->eye.z));
    return sqrtf(dx * dx + dy * dy + dz * dz) * 1.0001f;
}

/* Is box b inside one of the ns shadow frusta? Only frusta whose face's screen rectangle holds
 * the box's rectangle are tested plane by plane (a box crossing the near plane is in none). */
static bool shadowed(const frusta_state *s, uint32_t ns, const sl_aabb *b, const sl_occ_view *v, uint64_t *tests)
{
    if (ns == 0)
        return false;
    sl_occ_rect r;
    int k = sl_occ_project_box(v, b, &r);
    if (k == SL_OCC_NEAR)
        return false;
    if (k == SL_OCC_OUT)
        return true; /* off screen: the frustum test with its slack kept it, no pixel shows it */
    float rmax = v->ortho ? 0 : far_dist(v, b);
    for (uint32_t i = 0; i < ns; i++) {
        const shadow *sh = &s->sh[i];
        if (r.x0 < sh->x0 || r.x1 > sh->x1 || r.y0 < sh->y0 || r.y1 > sh->y1)
            continue;
        (*tests)++;
        if (in_shadow(sh, b, v, rmax))
            return true;
    }
    return false;
}

/* Heap order: x goes below y in a min-heap of "better" faces (so the worst sits on top). */
static inline bool worse(face_pick x, face_pick y)
{
    return x.quality < y.quality || (x.quality == y.quality && x.face > y.face);
}

static void sift(face_pick *a, uint32_t i, uint32_t n)
{
    face_pick x = a[i];
    for (;;) {
        uint32_t l = 2 * i + 1, r = l + 1, m = i;
        face_pick mv = x;
        if (l < n && worse(a[l], mv))
            m = l, mv = a[l];
        if (r < n && worse(a[r], mv))
            m = r;
        if (m == i)
            break;
        a[i] = a[m];
        i = m;
    }
    a[i] = x;
}

/* Sort best first, in place and without allocating (heapsort on the "worse" order). */
static void sort_faces(face_pick *a, uint32_t n)
{
    for (uint32_t i = n / 2; i-- > 0;)
        sift(a, i, n);
    for (uint32_t m = n; m > 1; m--) {
        face_pick t = a[0];
        a[0] = a[m - 1];
        a[m - 1] = t;
        sift(a, 0, m - 1);
    }
}

/* The walk's question (sl_occ_walk): boxes against the frame's shadow frusta; every object
 * reached is reported. */
typedef struct walk_ctx {
    const frusta_state *s;
    uint32_t ns;
    const sl_occ_view *v;
    uint64_t tests;
} walk_ctx;

static bool skip(void *ctx, uint32_t slot, const sl_aabb *box)
{
    (void)slot;
    walk_ctx *f = ctx;
    return shadowed(f->s, f->ns, box, f->v, &f->tests);
}

static sl_status frusta_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                             sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    (void)err;
    frusta_state *s = state;
    double t0 = sl_now();
    sl_occ_view v;
    sl_occ_view_init(&v, view);
    uint32_t np = sl_occ_base_select(&s->b, &v, &s->cfg.c, &stats->nodes_visited);
    /* rank the chosen proxies' faces */
    uint32_t nf = 0;
    for (uint32_t i = 0; i < np; i++) {
        const sl_occ_proxy *p = &s->b.occ->proxies[s->b.picks[i].proxy];
        for (uint32_t j = 0; j < p->face_count && nf < s->face_cap; j++) {
            uint32_t fi = p->face_first + j;
            float q = face_quality(&s->b.occ->faces[fi], &v);
            if (q > 0)
                s->faces[nf++] = (face_pick){fi, q};
        }
    }
    sort_faces(s->faces, nf);
    uint32_t ns = 0;
    for (uint32_t i = 0; i < nf && ns < s->cfg.frusta; i++)
        if (make_shadow(s->b.occ, &s->b.occ->faces[s->faces[i].face], &v, &s->sh[ns]))
            ns++;
    double t1 = sl_now();
    walk_ctx f = {s, ns, &v, 0};
    sl_occ_walk w = {skip, NULL, &f, out, 0};
    uint64_t tested = 0;
    uint64_t visited = sl_occ_walk_bvh(s->b.bvh, &v, &w, &tested);
    uint32_t k = w.count;
    uint64_t otests = f.tests;
    double t2 = sl_now();
    sl_cull_sort_ids(out, k, s->b.sort_scratch);
    double t3 = sl_now();
    stats->nodes_visited += visited;
    stats->objects_tested = tested;
    stats->occlusion_tests = otests;
    sl_cull_phase(stats, "select", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "traverse", sl_cull_ms(t1, t2));
    sl_cull_phase(stats, "sort", sl_cull_ms(t2, t3));
    *count = k;
    return SL_OK;
}

const sl_cull_method sl_cull_method_frusta = {
    .name = "frusta",
    .suits = "scenes with a few large convex occluders close to the eye",
    .summary = "object-space shadow frusta of the best convex occluder faces each frame, a box culled when "
               "inside one frustum (Hudson et al. 1997)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .depth = SL_DEPTH_INV_W,
    .config_size = sizeof(frusta_config),
    .configure = frusta_configure,
    .create_with = frusta_create,
    .cull = frusta_cull,
    .scene_changed = frusta_scene_changed,
    .destroy = frusta_destroy,
    .applicable = sl_occ_applicable,
};

/* hom: hierarchical occlusion maps, after Zhang, Manocha, Hudson & Hoff, "Visibility Culling
 * using Hierarchical Occlusion Maps" (SIGGRAPH 1997), sections 3-5, as summarised in the SIGGRAPH
 * 2000 course "Visibility, problems, techniques and applications" (section 6.2).
 *
 * Occlusion is split into a 2D overlap test and a depth test:
 *  - occluders: the best proxies in the frustum by Coorg-Teller quality under a triangle budget
 *    (occlusion/select.c), rendered once into the conservative rasterizer ("white on black");
 *  - the opacity pyramid: level 0 is the subtile grid (8x4 pixels), opacity 1 where the subtile's
 *    farthest depth is above the clear value (every pixel covered) and 0 otherwise (a partially
 *    covered subtile counts as empty, which under-estimates opacity: safe); each coarser level
 *    averages its 2x2 children;
 *  - the depth estimation buffer (DEB): a coarse screen grid (`deb` pixels a cell), each cell the
 *    farthest depth of every occluder whose screen rectangle touches it;
 *  - a box passes the overlap test when the pyramid shows its rectangle opaque: starting at the
 *    coarsest level where it spans at most 2x2 entries, an entry at or above `threshold` counts
 *    as covered, a lower one is refined through its children, and a level-0 entry below it is a
 *    hole; then the depth test: the box's nearest depth must be farther than every DEB cell its
 *    rectangle touches (depth=deb), or than the rasterizer's per-pixel depth (depth=zbuffer, the
 *    paper's "no-background z-buffer").
 * threshold = 1 (default) is conservative; below 1 small holes "dissolve" and the method declares
 * itself aggressive (approximate culling, section 5.3). */
#include "cull/occlusion/base.h"
#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/pyramid.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/view.h"
#include "cull/occlusion/walk.h"
#include "cull/occlusion_debug.h"

#include <math.h>

typedef struct hom_config {
    sl_occ_common c;
    float threshold;
    uint32_t deb;
    uint32_t depth;            /* 0 deb, 1 zbuffer */
} hom_config;

typedef struct hom_state {
    sl_occ_base b;             /* BVH, proxies, selection buffers */
    hom_config cfg;
    sl_occ_raster r;
    sl_occ_pyramid pyr;        /* opacity pyramid */
    /* depth estimation buffer */
    float *deb;
    uint32_t dw, dh;
    size_t deb_cap;
    uint64_t overlap_reads;
} hom_state;

static const char g_help[] =
    "threshold=0.01..1 (default 1): opacity that counts as opaque; below 1 the method is aggressive\n"
    "depth=deb|zbuffer (default deb): depth test against the depth estimation buffer or the rasterizer\n"
    "deb=8..512 (default 32): edge of a depth estimation buffer cell in pixels\n" SL_OCC_HELP_RES SL_OCC_HELP_RASTER
    "occluders=0..4096 (default 128): most occluders chosen per frame by Coorg-Teller quality\n"
    "budget=0..10000000 (default 20000): triangle budget of the chosen occluders\n"
    "min_quality=NUMBER (default 0.0005): least quality (solid angle, sr) of an occluder\n"
    "inset=0.01..10 (default 0.01 with res=any and inner=hull, raised where float rounding needs more; else 0.1): "
    "metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n"
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n" SL_OCC_HELP_DEBUG;

static sl_status hom_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    static const char *const depth_names[] = {"deb", "zbuffer"};
    hom_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "threshold", 1.0f, 0.01f, 1.0f, &c->threshold, err)) != SL_OK ||
        (st = sl_opts_enum(o, "depth", depth_names, 2, 0, &c->depth, err)) != SL_OK ||
        (st = sl_opts_u32(o, "deb", 32, 8, 512, &c->deb, err)) != SL_OK ||
        (st = sl_occ_configure_common(o,
                                      SL_OCC_OPT_RASTER | SL_OCC_OPT_SELECT | SL_OCC_OPT_DEBUG | SL_OCC_OPT_RES |
                                          SL_OCC_OPT_THIN_INSET,
                                      128, 20000, &c->c, err)) != SL_OK)
        return st;
    *g = c->threshold < 1.0f ? SL_AGGRESSIVE : sl_occ_res_guarantee(&c->c);
    return SL_OK;
}

static void hom_destroy(void *state)
{
    hom_state *s = state;
    if (!s)
        return;
    sl_allocator a = s->b.alloc;
    sl_occ_raster_free(&s->r);
    sl_occ_pyramid_free(&s->pyr, &a);
    sl_free(&a, s->deb, s->deb_cap * sizeof(float));
    sl_occ_base_free(&s->b);
    sl_free(&a, s, sizeof *s);
}

static sl_status hom_create(sl_scene scene, const void *config, const sl_cull_extras *extras,
                            const sl_allocator *alloc, void **state, sl_error *err)
{
    hom_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "hom: out of memory");
    s->cfg = *(const hom_config *)config;
    sl_status st = sl_occ_base_init(&s->b, scene, "hom", &s->cfg.c, true, 0, true, extras, alloc, err);
    if (st != SL_OK) {
        sl_free(alloc, s, sizeof *s);
        return st;
    }
    if ((st = sl_occ_raster_init(&s->r, &s->cfg.c, s->b.occ, alloc, err)) != SL_OK) {
        sl_error_prefix(err, "hom");
        hom_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status hom_scene_changed(void *state, sl_error *err)
{
    hom_state *s = state;
    return sl_occ_base_scene_changed(&s->b, err);
}

/* The pyramid and the DEB for a w x h screen (allocates only when the resolution changes). */
static sl_status size_buffers(hom_state *s, uint32_t w, uint32_t h, sl_error *err)
{
    bool resized;
    sl_status st = sl_occ_pyramid_size(&s->pyr, &s->b.alloc, s->r.ctx, w, h, &resized, err);
    if (st != SL_OK || (!resized && s->deb))
        return st;
    s->dw = (w + s->cfg.deb - 1) / s->cfg.deb;
    s->dh = (h + s->cfg.deb - 1) / s->cfg.deb;
    size_t dn = (size_t)s->dw * s->dh;
    sl_free(&s->b.alloc, s->deb, s->deb_cap * sizeof(float));
    s->deb = sl_alloc(&s->b.alloc, dn * sizeof(float));
    s->deb_cap = s->deb ? dn : 0;
    if (!s->deb)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for the depth estimation buffer");
    return SL_OK;
}

/* Level 0 from the buffer (1: every pixel of the subtile covered), then 2x2 averages over the
 * children that exist. */
static void build_pyramid(hom_state *s)
{
    sl_occ_pyramid *p = &s->pyr;
    size_t n0 = (size_t)p->lw[0] * p->lh[0];
    sl_occ_pyramid_read_base(p, s->r.ctx);
    for (size_t i = 0; i < n0; i++)
        p->data[i] = p->data[i] > 0.0f ? 1.0f : 0.0f;
    for (uint32_t l = 1; l < p->levels; l++) {
        const float *src = p->data + p->loff[l - 1];
        float *dst = p->data + p->loff[l];
        uint32_t sw = p->lw[l - 1], sh = p->lh[l - 1], w = p->lw[l], h = p->lh[l];
        for (uint32_t y = 0; y < h; y++)
            for (uint32_t x = 0; x < w; x++) {
                float sum = 0;
                int cnt = 0;
                for (uint32_t dy = 0; dy < 2; dy++)
                    for (uint32_t dx = 0; dx < 2; dx++) {
                        uint32_t cx = 2 * x + dx, cy = 2 * y + dy;
                        if (cx < sw && cy < sh) {
                            sum += src[(size_t)cy * sw + cx];
                            cnt++;
                        }
                    }
                dst[(size_t)y * w + x] = sum / (float)cnt; /* four 1s average to exactly 1 */
            }
    }
}

/* Write far depth d over the DEB cells of pixel rectangle r. */
static void deb_write(hom_state *s, const sl_occ_rect *r, float d)
{
    uint32_t cx0 = (uint32_t)r->x0 / s->cfg.deb, cx1 = (uint32_t)(r->x1 - 1) / s->cfg.deb;
    uint32_t cy0 = (uint32_t)r->y0 / s->cfg.deb, cy1 = (uint32_t)(r->y1 - 1) / s->cfg.deb;
    for (uint32_t cy = cy0; cy <= cy1; cy++)
        for (uint32_t cx = cx0; cx <= cx1; cx++) {
            float *p = &s->deb[(size_t)cy * s->dw + cx];
            *p = sl_occ_minf(*p, d);
        }
}

/* Screen rectangle, nearest depth (in r->dnear) and farthest depth of a convex polygon or point
 * set. False when it lies
 * wholly outside one clip plane (nothing to write). A polygon crossing the near plane covers the
 * whole screen; its farthest depth is at the point of largest w (1/w) or z (orthographic). */
static bool poly_rect(const sl_occ_view *v, const sl_vec3 *p, uint32_t n, sl_occ_rect *r, float *far_d)
{
    float nd = 0;
    const float *m = v->vp.m;
    const float hw = 0.5f * (float)v->width, hh = 0.5f * (float)v->height;
    unsigned all = 63;
    bool near_cross = false;
    float minx = INFINITY, maxx = -INFINITY, miny = INFINITY, maxy = -INFINITY, fd = INFINITY;
    for (uint32_t i = 0; i < n; i++) {
        float x = m[0] * p[i].x + m[4] * p[i].y + m[8] * p[i].z + m[12];
        float y = m[1] * p[i].x + m[5] * p[i].y + m[9] * p[i].z + m[13];
        float z = m[2] * p[i].x + m[6] * p[i].y + m[10] * p[i].z + m[14];
        float w = m[3] * p[i].x + m[7] * p[i].y + m[11] * p[i].z + m[15];
        all &= (x < -w ? 1u : 0u) | (x > w ? 2u : 0u) | (y < -w ? 4u : 0u) | (y > w ? 8u : 0u) | (z < -w ? 16u : 0u) |
               (z > w ? 32u : 0u);
        if (!(w > 0)) {
            near_cross = true;
            continue;
        }
        float inv = 1.0f / w;
        float dd = v->ortho ? 0.5f * (1.0f - z * inv) : inv;
        fd = sl_occ_minf(fd, dd);
        nd = sl_occ_maxf(nd, dd);
        if (z < -w || w < 1e-5f) {
            near_cross = true;
            continue;
        }
        float sx = (x * inv) * hw + hw, sy = hh - (y * inv) * hh;
        minx = sl_occ_minf(minx, sx);
        maxx = sl_occ_maxf(maxx, sx);
        miny = sl_occ_minf(miny, sy);
        maxy = sl_occ_maxf(maxy, sy);
    }
    if (all || !isfinite(fd))
        return false;
    /* nudged farther by 2^-20 relative for the rounding of the transform */
    *far_d = sl_occ_maxf(fd - fabsf(fd) * SL_MARGIN_REL_F, 0.0f);
    if (near_cross || !isfinite(minx) || !isfinite(maxx) || !isfinite(miny) || !isfinite(maxy)) {
        *r = (sl_occ_rect){0, 0, (int32_t)v->width, (int32_t)v->height, 0};
        return true;
    }
    const float eps = SL_MARGIN_RECT_PX;
    float fx0 = sl_occ_maxf(floorf(minx - eps), 0.0f), fx1 = sl_occ_minf(floorf(maxx + eps) + 1.0f, (float)v->width);
    float fy0 = sl_occ_maxf(floorf(miny - eps), 0.0f), fy1 = sl_occ_minf(floorf(maxy + eps) + 1.0f, (float)v->height);
    if (!(fx0 < fx1) || !(fy0 < fy1))
        return false;
    *r = (sl_occ_rect){(int32_t)fx0, (int32_t)fy0, (int32_t)fx1, (int32_t)fy1, nd + fabsf(nd) * SL_MARGIN_REL_F};
    return true;
}

/* Clip convex polygon p[0..n) to the slab lo <= dot(a, x) <= hi (Sutherland-Hodgman, both sides). */
static uint32_t clip_slab(const sl_vec3 *p, uint32_t n, sl_vec3 a, float lo, float hi, sl_vec3 *out)
{
    sl_vec3 tmp[24];
    uint32_t m = 0;
    for (int side = 0; side < 2; side++) {
        const sl_vec3 *src = side ? tmp : p;
        uint32_t sn = side ? m : n;
        sl_vec3 *dst = side ? out : tmp;
        uint32_t k = 0;
        for (uint32_t i = 0; i < sn && k + 2 < 24; i++) {
            sl_vec3 u = src[i], w = src[(i + 1) % sn];
            float du = a.x * u.x + a.y * u.y + a.z * u.z, dw = a.x * w.x + a.y * w.y + a.z * w.z;
            float fu = side ? hi - du : du - lo, fw = side ? hi - dw : dw - lo;
            if (fu >= 0)
                dst[k++] = u;
            if ((fu >= 0) != (fw >= 0)) {
                float t = fu / (fu - fw);
                dst[k++] = (sl_vec3){u.x + t * (w.x - u.x), u.y + t * (w.y - u.y), u.z + t * (w.z - u.z)};
            }
        }
        m = k;
        if (side == 0 && m < 3)
            return 0;
    }
    return m;
}

/* The DEB: each chosen occluder writes its farthest depth into the cells its screen rectangle
 * touches. A prism does it per front face, each face cut into slabs across its depth so that a
 * long façade seen at a grazing angle does not spread its farthest depth over the whole street;
 * the slabs' union is the face, so every covered pixel still gets a depth no nearer than the
 * occluder there. Other proxies use their box. A slab (or box) that the rendered occluders hide
 * completely is never the front surface at any pixel and writes nothing: the front surface at a
 * covered pixel belongs to a slab that is not hidden, whose rectangle contains the pixel, so the
 * cell still holds a depth no nearer than it. Without this, the hidden buildings behind a
 * street's façades would drag every cell to their far depth. */
static void build_deb(hom_state *s, const sl_occ_view *v, const uint32_t *proxies, uint32_t n)
{
    size_t dn = (size_t)s->dw * s->dh;
    for (size_t i = 0; i < dn; i++)
        s->deb[i] = INFINITY;
    const sl_occ_set *o = s->b.occ;
    for (uint32_t i = 0; i < n; i++) {
        const sl_occ_proxy *pr = &o->proxies[proxies[i]];
        sl_occ_rect r;
        float far_d;
        if (pr->kind != SL_OCC_PRISM || pr->face_count == 0) {
            sl_aabb b = sl_occ_proxy_box(o, pr);
            sl_vec3 c[8];
            for (int k = 0; k < 8; k++)
                c[k] = (sl_vec3){(k & 1) ? b.max.x : b.min.x, (k & 2) ? b.max.y : b.min.y, (k & 4) ? b.max.z : b.min.z};
            /* the box's corners as a point set: its rectangle and farthest corner bound the proxy */
            if (poly_rect(v, c, 8, &r, &far_d) &&
                !(r.dnear > 0 && sl_occ_raster_test(&s->r, r.x0, r.y0, r.x1, r.y1, r.dnear) != SL_RASTER_VISIBLE))
                deb_write(s, &r, far_d);
            continue;
        }
        for (uint32_t fi = 0; fi < pr->face_count; fi++) {
            const sl_occ_face *f = &o->faces[pr->face_first + fi];
            const sl_vec3 *p = o->face_verts + f->first;
            /* front faces only: a closed prism's back faces lie behind its front faces */
            float side = v->ortho ? -(f->normal.x * v->fwd.x + f->normal.y * v->fwd.y + f->normal.z * v->fwd.z)
                                  : f->normal.x * (v->eye.x - p[0].x) + f->normal.y * (v->eye.y - p[0].y) +
                                        f->normal.z * (v->eye.z - p[0].z);
            if (!(side > 0))
                continue;
            /* slab direction: the face's extent along the view direction, in eye depth */
            float dmin = INFINITY, dmax = -INFINITY;
            for (uint32_t k = 0; k < f->count; k++) {
                float d = v->fwd.x * p[k].x + v->fwd.y * p[k].y + v->fwd.z * p[k].z;
                dmin = sl_occ_minf(dmin, d);
                dmax = sl_occ_maxf(dmax, d);
            }
            float e = v->fwd.x * v->eye.x + v->fwd.y * v->eye.y + v->fwd.z * v->eye.z;
            float znear = sl_occ_maxf(dmin - e, 0.5f);
            uint32_t slabs = v->ortho || f->count > 16 ? 1 : (uint32_t)sl_occ_minf(ceilf((dmax - dmin) / (0.25f * znear)), 8.0f);
            slabs = slabs < 1 ? 1 : slabs;
            for (uint32_t k = 0; k < slabs; k++) {
                float lo = dmin + (dmax - dmin) * (float)k / (float)slabs;
                float hi = k + 1 == slabs ? dmax : dmin + (dmax - dmin) * (float)(k + 1) / (float)slabs;
                sl_vec3 q[24];
                const sl_vec3 *piece = p;
                uint32_t m = f->count;
                if (slabs > 1) {
                    m = clip_slab(p, f->count, v->fwd, lo, hi, q);
                    piece = q;
                }
                if (m < 3 || !poly_rect(v, piece, m, &r, &far_d))
                    continue;
                /* a slab hidden behind the other occluders is never the front surface: skip it */
                if (r.dnear > 0 && sl_occ_raster_test(&s->r, r.x0, r.y0, r.x1, r.y1, r.dnear) != SL_RASTER_VISIBLE)
                    continue;
                deb_write(s, &r, far_d);
            }
        }
    }
}

/* Overlap test: every subtile the rectangle touches is opaque (at the threshold). */
static bool overlap_covered(hom_state *s, const sl_occ_rect *r)
{
    uint32_t sx0 = (uint32_t)r->x0 >> 3, sx1 = (uint32_t)(r->x1 - 1) >> 3;
    uint32_t sy0 = (uint32_t)r->y0 >> 2, sy1 = (uint32_t)(r->y1 - 1) >> 2;
    const sl_occ_pyramid *p = &s->pyr;
    uint32_t l = 0;
    while (l + 1 < p->levels && ((sx1 >> l) - (sx0 >> l) > 1 || (sy1 >> l) - (sy0 >> l) > 1))
        l++;
    /* explicit stack of (level, x, y) entries to examine */
    struct {
        uint8_t l;
        uint32_t x, y;
    } stack[4 * SL_OCC_MAX_LEVELS + 8];
    uint32_t sp = 0;
    for (uint32_t y = sy0 >> l; y <= sy1 >> l; y++)
        for (uint32_t x = sx0 >> l; x <= sx1 >> l; x++) {
            stack[sp].l = (uint8_t)l;
            stack[sp].x = x;
            stack[sp].y = y;
            sp++;
        }
    float t = s->cfg.threshold;
    while (sp) {
        sp--;
        uint32_t L = stack[sp].l, x = stack[sp].x, y = stack[sp].y;
        s->overlap_reads++;
        float o = p->data[p->loff[L] + (size_t)y * p->lw[L] + x];
        if (o >= t)
            continue;
        if (L == 0 || o <= 0.0f)
            return false;
        /* refine: the children that exist and meet the rectangle */
        for (uint32_t dy = 0; dy < 2; dy++)
            for (uint32_t dx = 0; dx < 2; dx++) {
                uint32_t cx = 2 * x + dx, cy = 2 * y + dy;
                if (cx >= p->lw[L - 1] || cy >= p->lh[L - 1])
                    continue;
                if (cx < (sx0 >> (L - 1)) || cx > (sx1 >> (L - 1)) || cy < (sy0 >> (L - 1)) || cy > (sy1 >> (L - 1)))
                    continue;
                stack[sp].l = (uint8_t)(L - 1);
                stack[sp].x = cx;
                stack[sp].y = cy;
                sp++;
            }
    }
    return true;
}

static bool occluded(hom_state *s, const sl_occ_view *v, const sl_aabb *b, sl_cull_stats *st)
{
    sl_occ_rect r;
    int k = sl_occ_project_box(v, b, &r);
    if (k == SL_OCC_OUT)
        return true;
    if (k == SL_OCC_NEAR)
        return false;
    st->occlusion_tests++;
    if (!overlap_covered(s, &r))
        return false;
    if (s->cfg.depth == 1)
        return sl_occ_raster_test(&s->r, r.x0, r.y0, r.x1, r.y1, r.dnear) != SL_RASTER_VISIBLE;
    uint32_t cx0 = (uint32_t)r.x0 / s->cfg.deb, cx1 = (uint32_t)(r.x1 - 1) / s->cfg.deb;
    uint32_t cy0 = (uint32_t)r.y0 / s->cfg.deb, cy1 = (uint32_t)(r.y1 - 1) / s->cfg.deb;
    for (uint32_t cy = cy0; cy <= cy1; cy++)
        for (uint32_t cx = cx0; cx <= cx1; cx++)
            if (!(r.dnear < s->deb[(size_t)cy * s->dw + cx]))
                return false;
    return true;
}

/* The walk's question (sl_occ_walk): boxes through the maps; every object reached is reported. */
typedef struct walk_ctx {
    hom_state *s;
    const sl_occ_view *v;
    sl_cull_stats *st;
} walk_ctx;

static bool skip(void *ctx, uint32_t slot, const sl_aabb *box)
{
    (void)slot;
    walk_ctx *f = ctx;
    return occluded(f->s, f->v, box, f->st);
}

static sl_status hom_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    hom_state *s = state;
    double t0 = sl_now();
    sl_occ_view v;
    sl_occ_view_init(&v, view);
    sl_status st = sl_occ_raster_begin(&s->r, &v, err);
    if (st == SL_OK)
        st = size_buffers(s, v.width, v.height, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "hom");
        return st;
    }
    s->overlap_reads = 0;
    uint32_t np = sl_occ_base_select(&s->b, &v, &s->cfg.c, &stats->nodes_visited);
    double t1 = sl_now();
    sl_occ_raster_render(&s->r, s->b.occ, &v, s->b.pick_ids, np);
    build_pyramid(s);
    build_deb(s, &v, s->b.pick_ids, np);
    double t2 = sl_now();
    walk_ctx f = {s, &v, stats};
    sl_occ_walk w = {skip, NULL, &f, out, 0};
    uint64_t tested = 0;
    uint64_t visited = sl_occ_walk_bvh(s->b.bvh, &v, &w, &tested);
    uint32_t k = w.count;
    double t3 = sl_now();
    sl_cull_sort_ids(out, k, s->b.sort_scratch);
    double t4 = sl_now();
    stats->nodes_visited += visited;
    stats->objects_tested = tested;
    stats->queries = s->r.queries;
    stats->pixel_queries = s->r.pixel_queries + s->overlap_reads * 32; /* a level-0 entry stands for 32 pixels */
    sl_cull_phase(stats, "select", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "maps", sl_cull_ms(t1, t2));
    sl_cull_phase(stats, "traverse", sl_cull_ms(t2, t3));
    sl_cull_phase(stats, "sort", sl_cull_ms(t3, t4));
    *count = k;
    sl_occ_levels lv = sl_occ_pyramid_levels(&s->pyr, true);
    if ((st = sl_occ_raster_end(&s->r, &lv, err)) != SL_OK)
        sl_error_prefix(err, "hom");
    return st;
}

const sl_cull_method sl_cull_method_hom = {
    .name = "hom",
    .suits = "any scene with occluders: building footprints, occluder meshes (Quake III maps, the city) or all_objects=true",
    .summary = "hierarchical occlusion maps: opacity pyramid of quality-selected occluder proxies plus a depth "
               "estimation buffer; threshold 1 conservative, below 1 aggressive (Zhang et al. 1997)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .res_culling = true,
    .depth = SL_DEPTH_INV_W,
    .config_size = sizeof(hom_config),
    .configure = hom_configure,
    .create_with = hom_create,
    .cull = hom_cull,
    .scene_changed = hom_scene_changed,
    .destroy = hom_destroy,
    .applicable = sl_occ_applicable,
};

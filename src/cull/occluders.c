/* Occluder proxies, their per-frame selection (Coorg & Teller, "Real-time occlusion culling for
 * models with large occluders", I3D 1997, section 3: the quality metric -A (N.V) / |D|^2), the
 * frame's view and box projection, the shared options, and the rasterizer wrapper used by every
 * image-space method. See occluders.h for the contracts and docs/occlusion.md for the design. */
#include "occluders.h"

#include <float.h>
#include <math.h>

/* ---- the view ---- */

void sl_occ_view_init(sl_occ_view *v, const sl_camera *cam)
{
    memset(v, 0, sizeof *v);
    v->cam = *cam;
    v->vp = sl_camera_view_proj(cam);
    v->eye = cam->position;
    sl_vec3 right, up;
    sl_camera_basis(cam, &v->fwd, &right, &up);
    v->fr = sl_camera_frustum(cam);
    for (int i = 0; i < 6; i++)
        v->slack[i] = sl_margin_plane_slack(v->fr.planes[i].d);
    v->ortho = cam->projection == SL_ORTHOGRAPHIC;
    v->width = cam->width;
    v->height = cam->height;
    v->depth = v->ortho ? SL_RASTER_DEPTH_LINEAR_Z : SL_RASTER_DEPTH_INV_W;
    if (v->ortho)
        v->focal = (float)cam->height / cam->ortho_height;
    else
        v->focal = (float)((double)cam->height / (2.0 * tan(0.5 * (double)cam->fov_y)));
    /* the near region's reach: the farthest near-rectangle corner (exact, in double), grown for
     * the float corners and the float matrix the renderer clips with */
    double nr = 0;
    if (!v->ortho) {
        double t = tan(0.5 * (double)cam->fov_y), a = (double)cam->width / (double)cam->height;
        nr = (double)cam->near_plane * sqrt(1.0 + t * t * (1.0 + a * a));
    }
    double mag = fabs((double)v->eye.x) + fabs((double)v->eye.y) + fabs((double)v->eye.z);
    v->near_reach = (float)(nr * 1.001 + 1e-6 * mag + 1e-6);
    v->near_depth = (float)((double)cam->near_plane * 1.001 + 1e-6 * mag + 1e-6);
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

int sl_occ_frustum_classify(const sl_occ_view *v, const sl_aabb *b, uint32_t mask)
{
    return sl_frustum_classify_box(v->fr.planes, v->slack, b, mask, true, NULL);
}

uint64_t sl_occ_walk_bvh(const struct sl_bvh_t *bvh, const sl_occ_view *v, sl_occ_walk *w,
                         uint64_t *objects_tested)
{
    uint64_t visited = 0, tested = 0;
    const float e[3] = {v->eye.x, v->eye.y, v->eye.z};
    if (bvh->node_slots) {
        uint32_t stack[SL_BVH_MAX_DEPTH + 1], masks[SL_BVH_MAX_DEPTH + 1], sp = 0, ni = 0, mask = 0x3f;
        for (;;) {
            const sl_bvh_node *n = &bvh->nodes[ni];
            visited++;
            int r = mask ? sl_occ_frustum_classify(v, &n->box, mask) : 0;
            if (r >= 0 && !(w->skip && w->skip(w->ctx, ni, &n->box))) {
                if (n->count == 0) {
                    bool right = sl_bvh_right_first(bvh->nodes, n, e);
                    stack[sp] = n->first + (right ? 0 : 1);
                    masks[sp] = (uint32_t)r;
                    sp++;
                    ni = n->first + (right ? 1 : 0);
                    mask = (uint32_t)r;
                    continue;
                }
                for (uint32_t j = n->first; j < n->first + n->count; j++) {
                    tested++;
                    const sl_aabb *ob = &bvh->object_bounds[j];
                    if (r && sl_occ_frustum_classify(v, ob, (uint32_t)r) < 0)
                        continue;
                    if (n->count > 1 && w->skip && w->skip(w->ctx, SL_NONE, ob))
                        continue;
                    if (w->visit)
                        w->visit(w->ctx, bvh->objects[j], ob);
                    else
                        w->out[w->count++] = bvh->objects[j];
                }
            }
            if (sp == 0)
                break;
            sp--;
            ni = stack[sp];
            mask = masks[sp];
        }
    }
    if (objects_tested)
        *objects_tested += tested;
    return visited;
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

/* A box coordinate pushed outward by 2^-20 of its magnitude (plus 2^-20 m): object boxes are
 * transformed in float, the oracle transforms vertices in double, so a vertex may lie an ulp or
 * two outside its object's box. */
static inline double grow_coord(float c, double dir)
{
    return (double)c + dir * (fabs((double)c) + 1.0) * SL_MARGIN_REL;
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

/* ---- options ---- */

sl_status sl_occ_configure_common(sl_opts *o, uint32_t which, uint32_t def_occluders, uint32_t def_budget,
                                  sl_occ_common *c, sl_error *err)
{
    static const char *const isa_names[] = {"auto", "scalar", "sse41", "avx2", "avx512"};
    sl_status st;
    if (which & SL_OCC_OPT_RASTER) {
        if ((st = sl_opts_u32(o, "threads", 1, 1, 16, &c->threads, err)) != SL_OK ||
            (st = sl_opts_enum(o, "isa", isa_names, 5, 0, &c->isa, err)) != SL_OK)
            return st;
    } else {
        c->threads = 1;
    }
    if (which & SL_OCC_OPT_SELECT) {
        if ((st = sl_opts_u32(o, "occluders", def_occluders, 0, 4096, &c->occluders, err)) != SL_OK ||
            (st = sl_opts_u32(o, "budget", def_budget, 0, 10000000, &c->budget, err)) != SL_OK ||
            (st = sl_opts_float(o, "min_quality", 0.0005f, 0.0f, 100.0f, &c->min_quality, err)) != SL_OK)
            return st;
    }
    if ((st = sl_opts_float(o, "inset", 0.1f, 0.01f, 10.0f, &c->inset, err)) != SL_OK ||
        (st = sl_opts_bool(o, "all_objects", false, &c->all_objects, err)) != SL_OK ||
        (st = sl_opts_u32(o, "leaf_size", SL_BVH_DEFAULT_LEAF_SIZE, 1, SL_BVH_MAX_LEAF_SIZE, &c->leaf_size, err)) !=
            SL_OK)
        return st;
    c->res_culling = c->res_any = false;
    if (which & SL_OCC_OPT_RES) {
        static const char *const res_names[] = {"any", "culling"};
        uint32_t res = 0;
        if ((st = sl_opts_enum(o, "res", res_names, 2, 0, &res, err)) != SL_OK)
            return st;
        c->res_culling = res == 1;
        c->res_any = res == 0;
        static const char *const inner_names[] = {"hull", "faces"};
        uint32_t inner = 0;
        if ((st = sl_opts_enum(o, "inner", inner_names, 2, 0, &inner, err)) != SL_OK)
            return st;
        c->inner_faces = inner == 1;
    }
    if (which & SL_OCC_OPT_DEBUG) {
        const char *d, *r;
        if ((st = sl_opts_string(o, "dump", &d, err)) != SL_OK ||
            (st = sl_opts_string(o, "record", &r, err)) != SL_OK ||
            (st = sl_opts_u32(o, "debug_frame", 0, 0, UINT32_MAX, &c->debug_frame, err)) != SL_OK)
            return st;
        if ((d && strlen(d) >= sizeof c->dump_buf - 16) || (r && strlen(r) >= sizeof c->record_buf))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s is longer than %zu characters", o->method,
                           d && strlen(d) >= sizeof c->dump_buf - 16 ? "dump" : "record", sizeof c->dump_buf - 16);
        if (d)
            snprintf(c->dump_buf, sizeof c->dump_buf, "%s", d);
        if (r)
            snprintf(c->record_buf, sizeof c->record_buf, "%s", r);
        c->dump = d ? c->dump_buf : NULL;
        c->record = r ? c->record_buf : NULL;
    }
    return SL_OK;
}

sl_status sl_occ_require_res_culling(const sl_opts *o, const sl_occ_common *c, const char *key, uint32_t value,
                                     sl_error *err)
{
    if (!c->res_any || value == 0)
        return SL_OK;
    return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                   "%s: %s=%u tests pixel centres of the culling resolution: it needs res=culling (with res=any, "
                   "the default, it is 0)",
                   o->method, key, value);
}

sl_status sl_occ_configure_mesh_tests(sl_opts *o, const sl_occ_common *c, sl_occ_mesh_tests *t, sl_error *err)
{
    sl_status st;
    if ((st = sl_opts_u32(o, "mesh_test", 64, 0, 100000, &t->mesh_test, err)) != SL_OK ||
        (st = sl_opts_u32(o, "sample_tris", c->res_any ? 0 : 64, 0, 1000000, &t->sample_tris, err)) != SL_OK ||
        (st = sl_opts_u32(o, "sample_px", 256, 0, SL_OCC_SAMPLED_MAX_PX, &t->sample_px, err)) != SL_OK ||
        (st = sl_occ_require_res_culling(o, c, "sample_tris", t->sample_tris, err)) != SL_OK)
        return st;
    /* a testing aid: shared=false leaves only the method's own test (tests/test_method_own.c) */
    bool shared;
    if ((st = sl_opts_bool(o, "shared", true, &shared, err)) != SL_OK)
        return st;
    if (!shared)
        t->mesh_test = t->sample_tris = 0;
    return SL_OK;
}

/* ---- the base of every method ---- */

static size_t at_least_one(size_t n) { return n ? n : 1; }

void sl_occ_base_free(sl_occ_base *b)
{
    const sl_allocator *a = &b->alloc;
    if (b->bvh_owned)
        sl_bvh_destroy(b->bvh);
    sl_occ_set_destroy(b->occ);
    sl_free(a, b->node_area, at_least_one(b->node_slots) * sizeof(float));
    sl_free(a, b->heap, at_least_one(b->pick_cap) * sizeof(sl_occ_pick));
    sl_free(a, b->picks, at_least_one(b->pick_cap) * sizeof(sl_occ_pick));
    sl_free(a, b->pick_ids, at_least_one(b->pick_cap) * sizeof(uint32_t));
    sl_free(a, b->sort_scratch, at_least_one(b->object_count) * sizeof(uint32_t));
    memset(b, 0, sizeof *b);
}

/* (Re)size the per-node areas to the tree and fill them (selecting methods only). */
static sl_status base_node_areas(sl_occ_base *b, sl_error *err)
{
    if (!b->pick_cap)
        return SL_OK;
    uint32_t n = b->bvh->node_slots;
    if (n != b->node_slots || !b->node_area) {
        sl_free(&b->alloc, b->node_area, at_least_one(b->node_slots) * sizeof(float));
        b->node_area = sl_alloc(&b->alloc, at_least_one(n) * sizeof(float));
        b->node_slots = b->node_area ? n : 0;
        if (!b->node_area)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for %u node areas", n);
    }
    sl_occ_node_areas(b->occ, b->bvh, b->node_area);
    return SL_OK;
}

sl_status sl_occ_base_init(sl_occ_base *b, sl_scene scene, const char *method, const sl_occ_common *c, bool faces,
                           uint32_t mesh_faces, bool select, const sl_cull_extras *extras, const sl_allocator *alloc,
                           sl_error *err)
{
    memset(b, 0, sizeof *b);
    b->alloc = *alloc;
    b->scene = scene;
    b->method = method;
    b->object_count = sl_scene_object_count(scene);
    /* res=any draws prisms face by face (render_prism_eroded): their vertices are kept */
    sl_occ_options oo = {c->inset, c->all_objects, faces || c->res_any, mesh_faces, c->res_any && !c->inner_faces};
    sl_status st = sl_cull_object_bvh(scene, extras, c->leaf_size, alloc, &b->bvh, &b->bvh_owned, err);
    if (st == SL_OK)
        st = sl_occ_set_create(scene, &oo, alloc, &b->occ, err);
    if (st == SL_OK) {
        b->sort_scratch = sl_alloc(alloc, at_least_one(b->object_count) * sizeof(uint32_t));
        if (select) {
            /* pick_cap is set only with every pick buffer, so that free sizes them right */
            size_t pc = at_least_one(c->occluders);
            b->heap = sl_alloc(alloc, pc * sizeof(sl_occ_pick));
            b->picks = sl_alloc(alloc, pc * sizeof(sl_occ_pick));
            b->pick_ids = sl_alloc(alloc, pc * sizeof(uint32_t));
            b->pick_cap = (uint32_t)pc;
        }
        if (!b->sort_scratch || (select && (!b->heap || !b->picks || !b->pick_ids)))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    if (st == SL_OK)
        st = base_node_areas(b, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", method);
        sl_occ_base_free(b);
    }
    return st;
}

sl_status sl_occ_base_scene_changed(sl_occ_base *b, sl_error *err)
{
    /* a shared tree is refitted by the handle's owner before this (accel.h) */
    sl_status st = b->bvh_owned ? sl_bvh_refit(b->bvh, b->scene, err) : SL_OK;
    if (st == SL_OK && b->bvh_owned)
        st = sl_bvh_rebuild_if_degraded(b->bvh, b->scene, 0, NULL, err);
    if (st == SL_OK)
        st = base_node_areas(b, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", b->method);
        return st;
    }
    sl_occ_set_scene_changed(b->occ);
    return SL_OK;
}

uint32_t sl_occ_base_select(sl_occ_base *b, const sl_occ_view *v, const sl_occ_common *c, uint64_t *nodes_visited)
{
    if (!b->pick_cap)
        return 0;
    uint32_t n = sl_occ_select(b->occ, v, b->bvh, b->node_area, c->occluders, c->budget, c->min_quality, b->heap,
                               b->picks, nodes_visited);
    for (uint32_t i = 0; i < n; i++)
        b->pick_ids[i] = b->picks[i].proxy;
    return n;
}

/* ---- screen pyramids ---- */

sl_status sl_occ_pyramid_size(sl_occ_pyramid *p, const sl_allocator *alloc, const sl_raster *ctx, uint32_t w,
                              uint32_t h, bool *resized, sl_error *err)
{
    if (resized)
        *resized = false;
    if (p->data && p->w == w && p->h == h)
        return SL_OK;
    uint32_t tx, ty;
    sl_raster_get_size(ctx, NULL, NULL, &tx, &ty);
    uint32_t lw = tx * 4, lh = ty * 2; /* 8x4 subtiles of 32x8 tiles */
    size_t total = 0;
    p->levels = 0;
    for (;;) {
        p->lw[p->levels] = lw;
        p->lh[p->levels] = lh;
        p->loff[p->levels] = total;
        total += (size_t)lw * lh;
        p->levels++;
        if ((lw == 1 && lh == 1) || p->levels == SL_OCC_MAX_LEVELS)
            break;
        lw = (lw + 1) / 2;
        lh = (lh + 1) / 2;
    }
    sl_free(alloc, p->data, p->cap * sizeof(float));
    p->data = sl_alloc(alloc, total * sizeof(float));
    p->cap = p->data ? total : 0;
    p->w = p->h = 0;
    if (!p->data)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for a %zu-entry pyramid", total);
    for (uint32_t i = 0; i < p->levels; i++)
        p->level_ptr[i] = p->data + p->loff[i];
    p->w = w;
    p->h = h;
    if (resized)
        *resized = true;
    return SL_OK;
}

void sl_occ_pyramid_free(sl_occ_pyramid *p, const sl_allocator *alloc)
{
    sl_free(alloc, p->data, p->cap * sizeof(float));
    memset(p, 0, sizeof *p);
}

void sl_occ_pyramid_read_base(sl_occ_pyramid *p, const sl_raster *ctx)
{
    (void)sl_raster_read_subtile_depth(ctx, p->data, (size_t)p->lw[0] * p->lh[0], NULL);
}

/* ---- prisms: footprint polygons shrunk inward ---- */

typedef struct { double x, y; } dvec2;

static double cross2(dvec2 a, dvec2 b) { return a.x * b.y - a.y * b.x; }
static dvec2 sub2(dvec2 a, dvec2 b) { return (dvec2){a.x - b.x, a.y - b.y}; }

static double seg_point_dist(dvec2 p, dvec2 a, dvec2 b)
{
    dvec2 ab = sub2(b, a), ap = sub2(p, a);
    double l2 = ab.x * ab.x + ab.y * ab.y, t = l2 > 0 ? (ap.x * ab.x + ap.y * ab.y) / l2 : 0;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    double dx = a.x + t * ab.x - p.x, dy = a.y + t * ab.y - p.y;
    return sqrt(dx * dx + dy * dy);
}

/* Do segments ab and cd intersect (touching counts)? */
static bool seg_intersect(dvec2 a, dvec2 b, dvec2 c, dvec2 d)
{
    double d1 = cross2(sub2(b, a), sub2(c, a)), d2 = cross2(sub2(b, a), sub2(d, a));
    double d3 = cross2(sub2(d, c), sub2(a, c)), d4 = cross2(sub2(d, c), sub2(b, c));
    if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
        return true;
    /* collinear or touching cases: close enough counts as touching */
    return seg_point_dist(c, a, b) == 0 || seg_point_dist(d, a, b) == 0 || seg_point_dist(a, c, d) == 0 ||
           seg_point_dist(b, c, d) == 0;
}

static double seg_seg_dist(dvec2 a, dvec2 b, dvec2 c, dvec2 d)
{
    if (seg_intersect(a, b, c, d))
        return 0;
    double m = seg_point_dist(a, c, d);
    m = fmin(m, seg_point_dist(b, c, d));
    m = fmin(m, seg_point_dist(c, a, b));
    return fmin(m, seg_point_dist(d, a, b));
}

static bool point_in_poly(dvec2 p, const dvec2 *q, uint32_t n)
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
static bool inset_polygon(const dvec2 *p, uint32_t n, double d, dvec2 *q)
{
    for (uint32_t i = 0; i < n; i++) {
        dvec2 a = p[(i + n - 1) % n], b = p[i], c = p[(i + 1) % n];
        dvec2 e0 = sub2(b, a), e1 = sub2(c, b);
        double l0 = hypot(e0.x, e0.y), l1 = hypot(e1.x, e1.y);
        if (!(l0 > 0) || !(l1 > 0))
            return false;
        dvec2 n0 = {-e0.y / l0, e0.x / l0}, n1 = {-e1.y / l1, e1.x / l1}; /* left = inward for CCW */
        double det = cross2(n0, n1);
        if (fabs(det) < 1e-9) {
            if (n0.x * n1.x + n0.y * n1.y < 0)
                return false; /* a spike folding back */
            q[i] = (dvec2){b.x + d * n0.x, b.y + d * n0.y};
        } else {
            double c0 = n0.x * b.x + n0.y * b.y + d, c1 = n1.x * b.x + n1.y * b.y + d;
            q[i] = (dvec2){(c0 * n1.y - c1 * n0.y) / det, (n0.x * c1 - n1.x * c0) / det};
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
        dvec2 pe = sub2(p[(i + 1) % n], p[i]), qe = sub2(q[(i + 1) % n], q[i]);
        if (!(pe.x * qe.x + pe.y * qe.y > 0) || hypot(qe.x, qe.y) < 1e-4)
            return false;
    }
    double need = d * (1.0 - 1e-6);
    for (uint32_t i = 0; i < n; i++) {
        dvec2 a = q[i], b = q[(i + 1) % n];
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
static bool ear_clip(const dvec2 *q, uint32_t n, uint32_t *work, uint32_t *tri)
{
    for (uint32_t i = 0; i < n; i++)
        work[i] = i;
    uint32_t m = n, t = 0, guard = 0;
    while (m > 3) {
        bool found = false;
        for (uint32_t k = 0; k < m && !found; k++) {
            uint32_t ia = work[(k + m - 1) % m], ib = work[k], ic = work[(k + 1) % m];
            dvec2 a = q[ia], b = q[ib], c = q[ic];
            if (!(cross2(sub2(b, a), sub2(c, b)) > 0))
                continue;
            bool empty = true;
            for (uint32_t j = 0; j < m && empty; j++) {
                uint32_t ij = work[j];
                if (ij == ia || ij == ib || ij == ic)
                    continue;
                dvec2 p = q[ij];
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
static void merge_convex(const dvec2 *q, uint32_t n, const uint32_t *tri, uint32_t *polys, uint32_t *len)
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
                            dvec2 x = q[tmp[s]], y = q[tmp[(s + 1) % k]], z = q[tmp[(s + 2) % k]];
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

/* Growable arrays of the set under construction. */
typedef struct build_ctx {
    const sl_allocator *a;
    sl_array proxies, pos, idx, faces, fverts;
    bool keep_verts;            /* store the faces' vertices (frusta, hom), not only their planes */
} build_ctx;

static bool push_face(build_ctx *b, uint32_t proxy, const sl_vec3 *v, uint32_t count)
{
    /* Newell normal and area of a planar polygon */
    double nx = 0, ny = 0, nz = 0, cx = 0, cy = 0, cz = 0;
    for (uint32_t i = 0; i < count; i++) {
        const sl_vec3 *p = &v[i], *q = &v[(i + 1) % count];
        nx += ((double)p->y - q->y) * ((double)p->z + q->z);
        ny += ((double)p->z - q->z) * ((double)p->x + q->x);
        nz += ((double)p->x - q->x) * ((double)p->y + q->y);
        cx += p->x;
        cy += p->y;
        cz += p->z;
    }
    double len = sqrt(nx * nx + ny * ny + nz * nz);
    if (!(len > 0))
        return true; /* degenerate: no face */
    sl_occ_face f;
    f.proxy = proxy;
    f.first = (uint32_t)b->fverts.count;
    f.count = b->keep_verts ? count : 0;
    f.normal = (sl_vec3){(float)(nx / len), (float)(ny / len), (float)(nz / len)};
    f.centre = (sl_vec3){(float)(cx / count), (float)(cy / count), (float)(cz / count)};
    f.area = (float)(0.5 * len);
    return (!b->keep_verts || sl_array_push(b->a, &b->fverts, sizeof(sl_vec3), v, count)) &&
           sl_array_push(b->a, &b->faces, sizeof f, &f, 1);
}

/* Make the prism proxy of footprint fi, or count it rejected. */
static sl_status add_prism(sl_occ_set *s, build_ctx *b, uint32_t fi, dvec2 *work_p, dvec2 *work_q, uint32_t *work_i,
                           uint32_t *tri, uint32_t *polys, uint32_t *plen, sl_vec3 *work_v, sl_error *err)
{
    sl_footprint_view fp = sl_scene_footprint(s->scene, fi);
    uint32_t n = fp.vertex_count;
    if (n < 3 || n > 512)
        return SL_OK;
    if (fp.object != SL_NONE && fp.object >= s->object_count)
        return SL_OK;
    for (uint32_t i = 0; i < n; i++)
        work_p[i] = (dvec2){fp.xy[2 * i], fp.xy[2 * i + 1]};
    /* the largest inset up to the option that can be certified, halving down to 1 cm */
    double d = s->opt.inset;
    bool ok = false;
    while (!ok && d >= 0.01 - 1e-9) {
        ok = (double)fp.roof_z - fp.base_z > 2 * d + 0.01 && inset_polygon(work_p, n, d, work_q) &&
             ear_clip(work_q, n, work_i, tri);
        if (!ok)
            d *= 0.5;
    }
    if (!ok) {
        s->prisms_rejected++;
        return SL_OK;
    }
    /* float rounding of the vertices must not undo the inset: d is at least 1 cm and the vertex
     * error is 1e-7 relative, so rounding to float keeps the prism inside for coordinates
     * below 1e4 m; beyond that the prism is not certified */
    double maxc = fmax(fabs((double)fp.roof_z), fabs((double)fp.base_z));
    for (uint32_t i = 0; i < n; i++)
        maxc = fmax(maxc, fmax(fabs(work_q[i].x), fabs(work_q[i].y)));
    if (maxc * 4.0 * FLT_EPSILON > 0.25 * d) {
        s->prisms_rejected++;
        return SL_OK;
    }
    double z0 = (double)fp.base_z + d, z1 = (double)fp.roof_z - d;
    d -= maxc * 4.0 * FLT_EPSILON; /* what the float vertices still guarantee */
    uint32_t pi = (uint32_t)b->proxies.count, v0 = (uint32_t)(b->pos.count / 3);
    sl_occ_proxy pr;
    memset(&pr, 0, sizeof pr);
    pr.object = fp.object;
    pr.kind = SL_OCC_PRISM;
    pr.mesh = SL_NONE;
    pr.source = fi;
    pr.first = (uint32_t)(b->idx.count / 3);
    pr.inset = (float)d;
    pr.closed = true;
    pr.enabled = true;
    pr.box = sl_aabb_empty();
    /* vertices: the base ring then the top ring */
    for (int ring = 0; ring < 2; ring++)
        for (uint32_t i = 0; i < n; i++) {
            float v[3] = {(float)work_q[i].x, (float)work_q[i].y, (float)(ring ? z1 : z0)};
            if (!sl_array_push(b->a, &b->pos, sizeof(float), v, 3))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for prism vertices");
            sl_aabb_grow(&pr.box, (sl_vec3){v[0], v[1], v[2]});
        }
    const float *P = NULL;
    uint32_t k = 0;
    /* walls: outward (right of the CCW edge), counter-clockwise seen from outside */
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        uint32_t wall[6] = {v0 + i, v0 + j, v0 + n + j, v0 + i, v0 + n + j, v0 + n + i};
        if (!sl_array_push(b->a, &b->idx, sizeof(uint32_t), wall, 6))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for prism triangles");
        k += 2;
    }
    /* roof (normal +z) and floor (normal -z) */
    for (uint32_t i = 0; i + 2 < n; i++) {
        uint32_t roof[3] = {v0 + n + tri[3 * i], v0 + n + tri[3 * i + 1], v0 + n + tri[3 * i + 2]};
        uint32_t floor_[3] = {v0 + tri[3 * i], v0 + tri[3 * i + 2], v0 + tri[3 * i + 1]};
        if (!sl_array_push(b->a, &b->idx, sizeof(uint32_t), roof, 3) ||
            !sl_array_push(b->a, &b->idx, sizeof(uint32_t), floor_, 3))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for prism triangles");
        k += 2;
    }
    pr.count = k;
    pr.triangles = k;
    /* faces: walls, convex roof and floor pieces */
    P = b->pos.data;
    pr.face_first = (uint32_t)b->faces.count;
    double area = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        sl_vec3 q[4] = {{P[3 * (v0 + i)], P[3 * (v0 + i) + 1], P[3 * (v0 + i) + 2]},
                        {P[3 * (v0 + j)], P[3 * (v0 + j) + 1], P[3 * (v0 + j) + 2]},
                        {P[3 * (v0 + n + j)], P[3 * (v0 + n + j) + 1], P[3 * (v0 + n + j) + 2]},
                        {P[3 * (v0 + n + i)], P[3 * (v0 + n + i) + 1], P[3 * (v0 + n + i) + 2]}};
        if (!push_face(b, pi, q, 4))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for faces");
    }
    merge_convex(work_q, n, tri, polys, plen);
    for (uint32_t i = 0; i + 2 < n; i++) {
        if (!plen[i])
            continue;
        for (int side = 0; side < 2; side++) {
            for (uint32_t m = 0; m < plen[i]; m++) {
                uint32_t vi = polys[(size_t)i * n + (side ? plen[i] - 1 - m : m)];
                work_v[m] = (sl_vec3){(float)work_q[vi].x, (float)work_q[vi].y, (float)(side ? z0 : z1)};
            }
            if (!push_face(b, pi, work_v, plen[i]))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for faces");
        }
    }
    pr.face_count = (uint32_t)b->faces.count - pr.face_first;
    const sl_occ_face *F = b->faces.data;
    for (uint32_t i = 0; i < pr.face_count; i++)
        area += F[pr.face_first + i].area;
    pr.area = (float)(0.5 * area);
    if (!sl_array_push(b->a, &b->proxies, sizeof pr, &pr, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for proxies");
    if (fp.object != SL_NONE)
        s->object_proxy[fp.object] = pi;
    s->prisms++;
    return SL_OK;
}

/* Area of a mesh under a transform, and (for static objects) its largest triangles as faces. */
static sl_status add_mesh_proxy(sl_occ_set *s, build_ctx *b, uint32_t kind, uint32_t mesh, const sl_affine *xf,
                                uint32_t object, uint32_t source, bool static_faces, sl_error *err)
{
    const struct sl_scene_t *sc = s->scene;
    const sl_mesh_rec *mr = &sl_scene_meshes(sc)[mesh];
    const float *pos = sl_scene_positions(sc) + 3 * mr->first_vertex;
    const uint32_t *idx = sl_scene_indices(sc) + mr->first_index;
    uint32_t pi = (uint32_t)b->proxies.count;
    sl_occ_proxy pr;
    memset(&pr, 0, sizeof pr);
    pr.object = object;
    pr.kind = kind;
    pr.mesh = mesh;
    pr.source = source;
    pr.triangles = mr->triangle_count;
    pr.enabled = true;
    pr.box = sl_aabb_transform(&mr->bounds, xf);
    pr.face_first = (uint32_t)b->faces.count;
    /* keep the K largest triangles (insertion into a small sorted list) */
    uint32_t K = static_faces ? s->opt.mesh_faces : 0;
    uint32_t best[64];
    float best_area[64];
    uint32_t nb = 0;
    double area = 0;
    for (uint32_t t = 0; t < mr->triangle_count; t++) {
        sl_vec3 v[3];
        for (int c = 0; c < 3; c++) {
            const float *p = pos + 3 * (size_t)idx[3 * t + c];
            v[c] = sl_affine_point(xf, (sl_vec3){p[0], p[1], p[2]});
        }
        double e1[3] = {(double)v[1].x - v[0].x, (double)v[1].y - v[0].y, (double)v[1].z - v[0].z};
        double e2[3] = {(double)v[2].x - v[0].x, (double)v[2].y - v[0].y, (double)v[2].z - v[0].z};
        double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
        float a = (float)(0.5 * sqrt(cx * cx + cy * cy + cz * cz));
        area += a;
        if (K == 0 || !(a > 0) || (nb == K && a <= best_area[nb - 1]))
            continue;
        uint32_t j = nb < K ? nb++ : K - 1;
        while (j > 0 && best_area[j - 1] < a) {
            best[j] = best[j - 1];
            best_area[j] = best_area[j - 1];
            j--;
        }
        best[j] = t;
        best_area[j] = a;
    }
    for (uint32_t i = 0; i < nb; i++) {
        sl_vec3 v[3];
        for (int c = 0; c < 3; c++) {
            const float *p = pos + 3 * (size_t)idx[3 * best[i] + c];
            v[c] = sl_affine_point(xf, (sl_vec3){p[0], p[1], p[2]});
        }
        if (!push_face(b, pi, v, 3))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for faces");
    }
    pr.face_count = (uint32_t)b->faces.count - pr.face_first;
    pr.area = (float)(0.5 * area);
    if (!sl_array_push(b->a, &b->proxies, sizeof pr, &pr, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for proxies");
    if (object != SL_NONE && s->object_proxy[object] == SL_NONE)
        s->object_proxy[object] = pi;
    if (kind == SL_OCC_MESH)
        s->meshes++;
    else
        s->scene_meshes++;
    return SL_OK;
}

void sl_occ_set_destroy(sl_occ_set *s)
{
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    sl_free(a, s->proxies, (size_t)s->proxy_count * sizeof(sl_occ_proxy));
    sl_free(a, s->object_proxy, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    sl_free(a, s->prism_xf, (size_t)(s->proxy_count ? s->proxy_count : 1) * sizeof(sl_affine));
    sl_free(a, s->prism_pos, (size_t)s->prism_vertex_count * 3 * sizeof(float));
    sl_free(a, s->prism_idx, (size_t)s->prism_tri_count * 3 * sizeof(uint32_t));
    sl_free(a, s->faces, (size_t)s->face_count * sizeof(sl_occ_face));
    sl_free(a, s->face_verts, (size_t)s->face_vert_count * sizeof(sl_vec3));
    for (uint32_t i = 0; s->cparts && i < s->cparts_count; i++)
        sl_occ_cparts_free(&s->cparts[i], a);
    sl_free(a, s->cparts, (size_t)(s->cparts_count ? s->cparts_count : 1) * sizeof(sl_occ_cparts));
    sl_free(a, s, sizeof *s);
}

/* Shrink a builder array to an exactly sized owned block (so that free sizes are known). */
static void *take(const sl_allocator *a, sl_array *arr, size_t elem)
{
    if (arr->count == 0) {
        sl_array_free(a, arr, elem);
        return NULL;
    }
    void *p = sl_realloc(a, arr->data, arr->cap * elem, arr->count * elem);
    if (!p)
        return NULL;
    arr->data = NULL;
    arr->cap = 0;
    return p;
}

sl_status sl_occ_set_create(sl_scene scene, const sl_occ_options *opt, const sl_allocator *alloc, sl_occ_set **out,
                            sl_error *err)
{
    *out = NULL;
    sl_occ_set *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory");
    s->alloc = *alloc;
    s->scene = scene;
    s->opt = *opt;
    if (s->opt.mesh_faces > 64)
        s->opt.mesh_faces = 64;
    s->object_count = sl_scene_object_count(scene);
    s->object_proxy = sl_alloc(alloc, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    build_ctx b = {alloc, {0}, {0}, {0}, {0}, {0}, opt->faces};
    sl_status st = SL_OK;
    dvec2 *wp = NULL, *wq = NULL;
    uint32_t *wi = NULL, *tri = NULL, *polys = NULL, *plen = NULL;
    sl_vec3 *wv = NULL;
    uint32_t maxn = 3;
    uint32_t nf = sl_scene_footprint_count(scene);
    for (uint32_t i = 0; i < nf; i++) {
        uint32_t n = sl_scene_footprint(scene, i).vertex_count;
        if (n <= 512)
            maxn = SL_MAX(maxn, n);
    }
    wp = sl_alloc(alloc, maxn * sizeof(dvec2));
    wq = sl_alloc(alloc, maxn * sizeof(dvec2));
    wi = sl_alloc(alloc, maxn * sizeof(uint32_t));
    tri = sl_alloc(alloc, 3 * (size_t)maxn * sizeof(uint32_t));
    polys = sl_alloc(alloc, (size_t)maxn * maxn * sizeof(uint32_t));
    plen = sl_alloc(alloc, maxn * sizeof(uint32_t));
    wv = sl_alloc(alloc, maxn * sizeof(sl_vec3));
    if (!s->object_proxy || !wp || !wq || !wi || !tri || !polys || !plen || !wv) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory");
        goto done;
    }
    for (uint32_t i = 0; i < s->object_count; i++)
        s->object_proxy[i] = SL_NONE;
    /* 1. footprint prisms */
    for (uint32_t i = 0; i < nf && st == SL_OK; i++)
        st = add_prism(s, &b, i, wp, wq, wi, tri, polys, plen, wv, err);
    /* 2. objects flagged OCCLUDER without a prism: their own mesh */
    const sl_object_rec *objects = sl_scene_objects(scene);
    const sl_affine *xfs = sl_scene_transforms(scene);
    for (uint32_t o = 0; o < s->object_count && st == SL_OK; o++) {
        if ((!(objects[o].flags & SL_OBJECT_OCCLUDER) && !s->opt.all_objects) || s->object_proxy[o] != SL_NONE)
            continue;
        sl_affine id = sl_affine_identity();
        const sl_affine *xf = objects[o].transform == SL_NONE ? &id : &xfs[objects[o].transform];
        st = add_mesh_proxy(s, &b, SL_OCC_MESH, objects[o].mesh, xf, o, SL_NONE,
                            s->opt.faces && !(objects[o].flags & SL_OBJECT_DYNAMIC), err);
    }
    /* 3. the scene's 3D occluder meshes (static, trusted to lie inside their objects) */
    uint32_t no = sl_scene_occluder_count(scene);
    for (uint32_t i = 0; i < no && st == SL_OK; i++) {
        sl_occluder_view ov = sl_scene_occluder(scene, i);
        st = add_mesh_proxy(s, &b, SL_OCC_SCENE_MESH, ov.mesh, &ov.transform, SL_NONE, i, s->opt.faces, err);
    }
    if (st != SL_OK)
        goto done;
    /* 4. screen_margin: the convex parts of the meshes MESH and SCENE_MESH proxies draw */
    if (s->opt.screen_margin) {
        s->cparts_count = sl_scene_mesh_count(scene);
        s->cparts = sl_calloc(alloc, s->cparts_count ? s->cparts_count : 1, sizeof(sl_occ_cparts));
        if (!s->cparts) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for convex parts");
            goto done;
        }
        const sl_occ_proxy *P = b.proxies.data;
        for (size_t i = 0; i < b.proxies.count && st == SL_OK; i++) {
            if (P[i].kind == SL_OCC_PRISM || P[i].mesh >= s->cparts_count || s->cparts[P[i].mesh].built)
                continue;
            const sl_mesh_rec *mr = &sl_scene_meshes(scene)[P[i].mesh];
            if (sl_occ_cparts_build(sl_scene_positions(scene) + 3 * (size_t)mr->first_vertex, mr->vertex_count,
                                    sl_scene_indices(scene) + mr->first_index, mr->triangle_count, alloc,
                                    &s->cparts[P[i].mesh]) != SL_OK)
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for convex parts");
        }
        if (st != SL_OK)
            goto done;
    }
    s->proxy_count = (uint32_t)b.proxies.count;
    s->prism_vertex_count = (uint32_t)(b.pos.count / 3);
    s->prism_tri_count = (uint32_t)(b.idx.count / 3);
    s->face_count = (uint32_t)b.faces.count;
    s->face_vert_count = (uint32_t)b.fverts.count;
    s->proxies = take(alloc, &b.proxies, sizeof(sl_occ_proxy));
    s->prism_pos = take(alloc, &b.pos, sizeof(float));
    s->prism_idx = take(alloc, &b.idx, sizeof(uint32_t));
    s->faces = take(alloc, &b.faces, sizeof(sl_occ_face));
    s->face_verts = take(alloc, &b.fverts, sizeof(sl_vec3));
    s->prism_xf = sl_alloc(alloc, (size_t)(s->proxy_count ? s->proxy_count : 1) * sizeof(sl_affine));
    if ((s->proxy_count && !s->proxies) || (s->prism_vertex_count && !s->prism_pos) ||
        (s->prism_tri_count && !s->prism_idx) || (s->face_count && !s->faces) ||
        (s->face_vert_count && !s->face_verts) || !s->prism_xf) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory");
        goto done;
    }
    /* remember each prism's object transform, to notice when the object moves */
    for (uint32_t p = 0; p < s->proxy_count; p++) {
        uint32_t o = s->proxies[p].object;
        s->prism_xf[p] = (o != SL_NONE && objects[o].transform != SL_NONE) ? xfs[objects[o].transform]
                                                                           : sl_affine_identity();
    }
done:
    sl_free(alloc, wp, maxn * sizeof(dvec2));
    sl_free(alloc, wq, maxn * sizeof(dvec2));
    sl_free(alloc, wi, maxn * sizeof(uint32_t));
    sl_free(alloc, tri, 3 * (size_t)maxn * sizeof(uint32_t));
    sl_free(alloc, polys, (size_t)maxn * maxn * sizeof(uint32_t));
    sl_free(alloc, plen, maxn * sizeof(uint32_t));
    sl_free(alloc, wv, maxn * sizeof(sl_vec3));
    sl_array_free(alloc, &b.proxies, sizeof(sl_occ_proxy));
    sl_array_free(alloc, &b.pos, sizeof(float));
    sl_array_free(alloc, &b.idx, sizeof(uint32_t));
    sl_array_free(alloc, &b.faces, sizeof(sl_occ_face));
    sl_array_free(alloc, &b.fverts, sizeof(sl_vec3));
    if (st != SL_OK) {
        sl_occ_set_destroy(s);
        return st;
    }
    *out = s;
    return SL_OK;
}

void sl_occ_set_scene_changed(sl_occ_set *s)
{
    const sl_object_rec *objects = sl_scene_objects(s->scene);
    const sl_affine *xfs = sl_scene_transforms(s->scene);
    for (uint32_t p = 0; p < s->proxy_count; p++) {
        sl_occ_proxy *pr = &s->proxies[p];
        if (pr->kind != SL_OCC_PRISM || pr->object == SL_NONE || !pr->enabled)
            continue;
        sl_affine now = objects[pr->object].transform != SL_NONE ? xfs[objects[pr->object].transform]
                                                                 : sl_affine_identity();
        if (memcmp(&now, &s->prism_xf[p], sizeof now) != 0)
            pr->enabled = false; /* the building moved off its footprint: never trust it again */
    }
}

/* ---- per-frame use ---- */

bool sl_occ_usable(const sl_occ_set *s, uint32_t proxy, const sl_occ_view *v)
{
    const sl_occ_proxy *p = &s->proxies[proxy];
    if (!p->enabled)
        return false;
    sl_aabb box = sl_occ_proxy_box(s, p);
    float g = 1e-3f + 1e-6f * (fabsf(v->eye.x) + fabsf(v->eye.y) + fabsf(v->eye.z));
    if (sl_occ_point_in_box(v->eye, &box, g))
        return false;
    sl_aabb ob = box;
    if (p->object != SL_NONE) {
        ob = sl_scene_object_bounds_array(s->scene)[p->object];
        if (sl_occ_point_in_box(v->eye, &ob, g))
            return false;
    }
    /* Only an occluder beyond the near plane hides anything (issue 12: the renderer clips a
     * surface the eye is centimetres from and sees through the hole). A MESH proxy of a two-sided
     * object is the object's own surface: the rasterizer path drops its triangles that reach the
     * near plane and frusta clips its faces, so it may be used where the eye is close. A proxy
     * inside a solid (a prism, a scene occluder, the two-sided rendering of a closed convex mesh
     * whose back faces the oracle skips) hides only what the solid's surface in front of it hides,
     * and that surface may be clipped: such a proxy is used only when its box and its object's
     * box keep out of the near region. */
    bool inside = p->kind != SL_OCC_MESH ||
                  (p->object != SL_NONE && (sl_scene_objects(s->scene)[p->object].flags & SL_OBJECT_CLOSED_CONVEX));
    if (inside && (!sl_occ_near_clear(v, &box) || !sl_occ_near_clear(v, &ob)))
        return false;
    if (p->kind != SL_OCC_PRISM || s->opt.screen_margin)
        return true;
    if (v->ortho)
        return p->inset * v->focal >= SL_OCC_MIN_INSET_PX;
    /* farthest corner: every point of the prism is at most this far from the eye */
    float dx = sl_occ_maxf(fabsf(box.min.x - v->eye.x), fabsf(box.max.x - v->eye.x));
    float dy = sl_occ_maxf(fabsf(box.min.y - v->eye.y), fabsf(box.max.y - v->eye.y));
    float dz = sl_occ_maxf(fabsf(box.min.z - v->eye.z), fabsf(box.max.z - v->eye.z));
    float dmax = sqrtf(dx * dx + dy * dy + dz * dz) * 1.0001f;
    return p->inset * v->focal >= SL_OCC_MIN_INSET_PX * dmax;
}

float sl_occ_quality(const sl_occ_set *s, uint32_t proxy, const sl_occ_view *v)
{
    const sl_occ_proxy *p = &s->proxies[proxy];
    if (p->kind == SL_OCC_PRISM) {
        float q = 0;
        for (uint32_t i = 0; i < p->face_count; i++) {
            const sl_occ_face *f = &s->faces[p->face_first + i];
            float dx = f->centre.x - v->eye.x, dy = f->centre.y - v->eye.y, dz = f->centre.z - v->eye.z;
            float d2 = dx * dx + dy * dy + dz * dz;
            if (!(d2 > 1e-6f))
                continue;
            float ndv = (f->normal.x * dx + f->normal.y * dy + f->normal.z * dz) / sqrtf(d2);
            if (ndv < 0)
                q += -f->area * ndv / d2;
        }
        return q;
    }
    sl_aabb b = sl_occ_proxy_box(s, p);
    float dx = 0.5f * (b.min.x + b.max.x) - v->eye.x, dy = 0.5f * (b.min.y + b.max.y) - v->eye.y;
    float dz = 0.5f * (b.min.z + b.max.z) - v->eye.z;
    float r2 = 0.25f * ((b.max.x - b.min.x) * (b.max.x - b.min.x) + (b.max.y - b.min.y) * (b.max.y - b.min.y) +
                        (b.max.z - b.min.z) * (b.max.z - b.min.z));
    float d2 = sl_occ_maxf(dx * dx + dy * dy + dz * dz, sl_occ_maxf(r2, 1e-6f));
    return p->area / d2;
}

void sl_occ_node_areas(const sl_occ_set *s, const struct sl_bvh_t *bvh, float *node_area)
{
    for (uint32_t i = bvh->node_slots; i-- > 0;) {
        const sl_bvh_node *n = &bvh->nodes[i];
        float a = 0;
        if (i == 1 && bvh->node_slots > 1 && bvh->nodes[0].count == 0) {
            node_area[i] = 0; /* padding slot */
            continue;
        }
        if (n->count) {
            for (uint32_t j = n->first; j < n->first + n->count; j++) {
                uint32_t p = s->object_proxy[bvh->objects[j]];
                if (p != SL_NONE)
                    a = sl_occ_maxf(a, s->proxies[p].area);
            }
        } else {
            a = sl_occ_maxf(node_area[n->first], node_area[n->first + 1]);
        }
        node_area[i] = a;
    }
}

/* Min-heap by quality of the best candidates so far. */
static void heap_push(sl_occ_pick *h, uint32_t *n, uint32_t cap, sl_occ_pick x)
{
    if (*n == cap) {
        if (x.quality <= h[0].quality)
            return;
        /* replace the worst and sift down */
        uint32_t i = 0;
        for (;;) {
            uint32_t l = 2 * i + 1, r = l + 1, m = i;
            float mq = x.quality;
            if (l < *n && h[l].quality < mq)
                m = l, mq = h[l].quality;
            if (r < *n && h[r].quality < mq)
                m = r;
            if (m == i)
                break;
            h[i] = h[m];
            i = m;
        }
        h[i] = x;
        return;
    }
    uint32_t i = (*n)++;
    while (i > 0 && h[(i - 1) / 2].quality > x.quality) {
        h[i] = h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h[i] = x;
}

static void consider(const sl_occ_set *s, const sl_occ_view *v, uint32_t p, float min_quality, sl_occ_pick *heap,
                     uint32_t *hn, uint32_t cap)
{
    /* twice the half area over the squared distance to the box bounds every face's -A(N.V)/|D|^2
     * summed: skip the exact sum when that cannot beat the worst kept so far */
    sl_aabb b = sl_occ_proxy_box(s, &s->proxies[p]);
    const float e[3] = {v->eye.x, v->eye.y, v->eye.z};
    float d2 = sl_bvh_dist2(&b, e);
    if (d2 > 0) {
        float bound = 2.0f * s->proxies[p].area / d2;
        if (bound < min_quality || (*hn == cap && bound <= heap[0].quality))
            return;
    }
    if (!sl_occ_usable(s, p, v))
        return;
    float q = sl_occ_quality(s, p, v);
    if (q >= min_quality && q > 0)
        heap_push(heap, hn, cap, (sl_occ_pick){p, q});
}

/* The selection's walk: prunes nodes whose proxies cannot qualify, offers every proxy reached. */
typedef struct select_walk {
    const sl_occ_set *s;
    const sl_occ_view *v;
    const float *node_area;
    float min_quality;
    sl_occ_pick *heap;
    uint32_t hn, cap;
    float e[3];
} select_walk;

static bool select_skip(void *ctx, uint32_t slot, const sl_aabb *box)
{
    select_walk *w = ctx;
    if (slot == SL_NONE)
        return false; /* objects: consider() prunes them */
    if (!(w->node_area[slot] > 0))
        return true;
    /* no quality below this node can reach min_quality, or beat the worst kept once the heap is
     * full (the walk goes near to far, so it fills with good ones early) */
    float d2 = sl_bvh_dist2(box, w->e), bound = 2.0f * w->node_area[slot];
    return !(d2 <= 0 || (bound >= w->min_quality * d2 && !(w->hn == w->cap && bound <= w->heap[0].quality * d2)));
}

static void select_visit(void *ctx, uint32_t object, const sl_aabb *box)
{
    (void)box;
    select_walk *w = ctx;
    uint32_t p = w->s->object_proxy[object];
    if (p != SL_NONE)
        consider(w->s, w->v, p, w->min_quality, w->heap, &w->hn, w->cap);
}

uint32_t sl_occ_select(const sl_occ_set *s, const sl_occ_view *v, const struct sl_bvh_t *bvh, const float *node_area,
                       uint32_t max_count, uint32_t tri_budget, float min_quality, sl_occ_pick *heap,
                       sl_occ_pick *out, uint64_t *nodes_visited)
{
    if (max_count == 0 || s->proxy_count == 0)
        return 0;
    select_walk sw = {s, v, node_area, min_quality, heap, 0, max_count, {v->eye.x, v->eye.y, v->eye.z}};
    sl_occ_walk w = {select_skip, select_visit, &sw, NULL, 0};
    uint64_t visited = sl_occ_walk_bvh(bvh, v, &w, NULL);
    uint32_t hn = sw.hn;
    /* proxies that belong to no object are not in the tree */
    for (uint32_t p = 0; p < s->proxy_count; p++) {
        if (s->proxies[p].object != SL_NONE)
            continue;
        sl_aabb b = s->proxies[p].box;
        if (sl_occ_frustum_classify(v, &b, 0x3f) >= 0)
            consider(s, v, p, min_quality, heap, &hn, max_count);
    }
    if (nodes_visited)
        *nodes_visited += visited;
    /* heap sort: best first */
    uint32_t n = hn;
    while (n > 1) {
        sl_occ_pick top = heap[0], x = heap[n - 1];
        n--;
        uint32_t i = 0;
        for (;;) {
            uint32_t l = 2 * i + 1, r = l + 1, m = i;
            float mq = x.quality;
            if (l < n && heap[l].quality < mq)
                m = l, mq = heap[l].quality;
            if (r < n && heap[r].quality < mq)
                m = r;
            if (m == i)
                break;
            heap[i] = heap[m];
            i = m;
        }
        heap[i] = x;
        heap[n] = top;
    }
    /* heap[0..hn) is now in decreasing quality; keep what fits in the budget */
    uint32_t k = 0;
    uint64_t tris = 0;
    for (uint32_t i = 0; i < hn; i++) {
        uint32_t t = s->proxies[heap[i].proxy].triangles;
        if (tris + t > tri_budget)
            continue;
        tris += t;
        out[k++] = heap[i];
    }
    /* render order: nearest first. The rasterizer merges two depth layers per block and keeps the
     * nearer one when they differ a lot, so front-to-back submission keeps the most occlusion;
     * the distance rides in the quality field from here on (insertion sort: k is small) */
    for (uint32_t i = 0; i < k; i++) {
        sl_aabb b = sl_occ_proxy_box(s, &s->proxies[out[i].proxy]);
        out[i].quality = sl_bvh_dist2(&b, sw.e);
    }
    for (uint32_t i = 1; i < k; i++) {
        sl_occ_pick x = out[i];
        uint32_t j = i;
        for (; j > 0 && out[j - 1].quality > x.quality; j--)
            out[j] = out[j - 1];
        out[j] = x;
    }
    return k;
}

/* ---- the rasterizer wrapper ---- */

sl_status sl_occ_raster_init(sl_occ_raster *r, const sl_occ_common *c, const sl_occ_set *set,
                             const sl_allocator *alloc, sl_error *err)
{
    memset(r, 0, sizeof *r);
    r->alloc = *alloc;
    r->threads = c->threads;
    r->isa = c->isa;
    r->erode = c->res_any;
    r->hull = c->res_any && !c->inner_faces;
    if (!sl_raster_isa_available((sl_raster_isa)c->isa))
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "isa=%s: this CPU cannot run it",
                       sl_raster_isa_name((sl_raster_isa)c->isa));
    r->batch_cap = (size_t)(set ? set->prism_tri_count : 0) * 3 + 3;
    r->batch = sl_alloc(alloc, r->batch_cap * sizeof(uint32_t));
    r->proxy_count = set ? set->proxy_count : 0;
    r->stamp = sl_calloc(alloc, r->proxy_count ? r->proxy_count : 1, sizeof(uint32_t));
    size_t mt = 1, mv = 1;
    for (uint32_t p = 0; p < r->proxy_count; p++) {
        const sl_occ_proxy *pr = &set->proxies[p];
        if (pr->kind == SL_OCC_MESH || (r->erode && pr->kind == SL_OCC_SCENE_MESH)) {
            mt = SL_MAX(mt, (size_t)pr->triangles);
            mv = SL_MAX(mv, (size_t)sl_scene_meshes(set->scene)[pr->mesh].vertex_count);
        } else if (r->erode && pr->kind == SL_OCC_PRISM) {
            /* its faces fanned: at most its triangles; their vertices projected */
            mt = SL_MAX(mt, (size_t)pr->count);
            for (uint32_t f = 0; f < pr->face_count; f++)
                mv = SL_MAX(mv, (size_t)set->faces[pr->face_first + f].count);
        }
    }
    if (r->hull)
        mt = SL_MAX(mt, (size_t)256); /* render_prism_hull's pieces: up to 64 + 128 vertices each */
    r->shrunk = sl_alloc(alloc, mt * 9 * sizeof(float));
    r->shrunk_idx = sl_alloc(alloc, mt * 3 * sizeof(uint32_t));
    r->shrunk_proj = sl_alloc(alloc, mv * sizeof(sl_occ_screen_vertex));
    r->shrunk_cap = mt;
    r->shrunk_proj_cap = mv;
    if (!r->batch || !r->stamp || !r->shrunk || !r->shrunk_idx || !r->shrunk_proj)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory for the occluder batch");
    for (size_t i = 0; i < mt * 3; i++)
        r->shrunk_idx[i] = (uint32_t)i;
    if (c->dump) {
        snprintf(r->dump_path, sizeof r->dump_path, "%s", c->dump);
        r->dump = r->dump_path;
    }
    if (c->record) {
        snprintf(r->record_path, sizeof r->record_path, "%s", c->record);
        r->record = r->record_path;
    }
    r->debug_frame = c->debug_frame;
    return SL_OK;
}

void sl_occ_raster_free(sl_occ_raster *r)
{
    sl_raster_destroy(r->ctx);
    sl_occ_recorder_destroy(r->rec);
    sl_free(&r->alloc, r->batch, r->batch_cap * sizeof(uint32_t));
    sl_free(&r->alloc, r->shrunk, r->shrunk_cap * 9 * sizeof(float));
    sl_free(&r->alloc, r->shrunk_idx, r->shrunk_cap * 3 * sizeof(uint32_t));
    sl_free(&r->alloc, r->shrunk_proj, r->shrunk_proj_cap * sizeof(sl_occ_screen_vertex));
    sl_free(&r->alloc, r->stamp, (size_t)(r->proxy_count ? r->proxy_count : 1) * sizeof(uint32_t));
    memset(r, 0, sizeof *r);
}

sl_status sl_occ_raster_begin(sl_occ_raster *r, const sl_occ_view *v, sl_error *err)
{
    sl_status st;
    if (!r->ctx || r->width != v->width || r->height != v->height) {
        sl_raster_destroy(r->ctx);
        r->ctx = NULL;
        sl_raster_options o = sl_raster_default_options(v->width, v->height);
        o.threads = r->threads;
        o.isa = (sl_raster_isa)r->isa;
        o.depth = v->depth;
        if ((st = sl_raster_create(&o, &r->alloc, &r->ctx, err)) != SL_OK)
            return st;
        r->width = v->width;
        r->height = v->height;
    }
    if ((st = sl_raster_begin_frame(r->ctx, v->depth, err)) != SL_OK)
        return st;
    if (++r->frame_id == 0) {
        memset(r->stamp, 0, (size_t)r->proxy_count * sizeof(uint32_t));
        r->frame_id = 1;
    }
    r->queries = r->pixel_queries = r->occluders_rendered = r->triangles_rendered = 0;
    sl_occ_recorder_destroy(r->rec);
    r->rec = NULL;
    if (r->record && r->frame == r->debug_frame) {
        sl_raster_options o = sl_raster_default_options(v->width, v->height);
        if ((st = sl_occ_recorder_create(&r->alloc, &o, v->depth, &r->rec, err)) != SL_OK)
            return st;
    }
    return SL_OK;
}

/* model-to-clip = vp * affine, in double, rounded once */
/* model-to-clip = vp * affine in double (column-major, m[col * 4 + row]) */
static void mul_affine_d(const sl_mat4 *vp, const sl_affine *t, double out[16])
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
static void mul_affine(const sl_mat4 *vp, const sl_affine *t, float out[16])
{
    double d[16];
    mul_affine_d(vp, t, d);
    for (int i = 0; i < 16; i++)
        out[i] = (float)d[i];
}

static sl_affine object_transform(const struct sl_scene_t *sc, uint32_t object)
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

static object_mesh get_object_mesh(const struct sl_scene_t *sc, uint32_t object)
{
    object_mesh o;
    o.mr = &sl_scene_meshes(sc)[sl_scene_objects(sc)[object].mesh];
    o.pos = sl_scene_positions(sc) + 3 * o.mr->first_vertex;
    o.idx = sl_scene_indices(sc) + o.mr->first_index;
    o.xf = object_transform(sc, object);
    return o;
}

/* Render a scene mesh with a transform, two-sided (open meshes are seen from both sides by the
 * oracle). */
static void render_mesh(sl_occ_raster *r, const struct sl_scene_t *sc, const sl_occ_view *v, uint32_t mesh,
                        sl_affine xf)
{
    const sl_mesh_rec *mr = &sl_scene_meshes(sc)[mesh];
    float m[16];
    mul_affine(&v->vp, &xf, m);
    const float *pos = sl_scene_positions(sc) + 3 * mr->first_vertex;
    const uint32_t *idx = sl_scene_indices(sc) + mr->first_index;
    (void)sl_raster_render_triangles(r->ctx, pos, mr->vertex_count, idx, mr->triangle_count, 12, m,
                                     SL_RASTER_CULL_NONE, NULL);
    if (r->rec)
        sl_occ_recorder_batch(r->rec, pos, 12, idx, mr->triangle_count, m, SL_RASTER_CULL_NONE);
}

/* Vertices projected at most once per sampled test, on first use (props have a few dozen; larger
 * meshes project per index). */
#define SAMPLED_VERTEX_CACHE 256


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
static void render_mesh_shrunk(sl_occ_raster *r, const struct sl_scene_t *sc, const sl_occ_view *v, uint32_t mesh,
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
static void render_prism_eroded(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const sl_occ_proxy *pr)
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
    if (!n)
        return;
    const float *to_clip = v->ortho ? g_shrunk_ortho : g_shrunk_persp;
    (void)sl_raster_render_triangles(r->ctx, r->shrunk, 3 * n, r->shrunk_idx, n, 12, to_clip, SL_RASTER_CULL_NONE,
                                     NULL);
    if (r->rec)
        sl_occ_recorder_batch(r->rec, r->shrunk, 12, r->shrunk_idx, n, to_clip, SL_RASTER_CULL_NONE);
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

/* Clip convex polygon (px, py, n) by the half-plane nx x + ny y >= off into (qx, qy); returns the
 * count. An intersection is computed from the segment's endpoints in a fixed order, so two faces
 * sharing an edge get the same points. */
static uint32_t clip_half(const double *px, const double *py, uint32_t n, double nx, double ny, double off,
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
            len = clip_half(ax[cur], ay[cur], len, hnx[e], hny[e], hoff[e], ax[cur ^ 1], ay[cur ^ 1], CAP);
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

static void render_prism_hull(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const sl_occ_proxy *pr)
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
 * drawn one by one, shrunk (render_mesh_shrunk). */
static void render_mesh_hull(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, uint32_t mesh, sl_affine xf)
{
    const sl_occ_cparts *cp = s->cparts ? &s->cparts[mesh] : NULL;
    if (!cp || !cp->built || v->ortho) {
        render_mesh_shrunk(r, s->scene, v, mesh, xf, NULL, 0);
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
            render_mesh_shrunk(r, s->scene, v, mesh, xf, cp->src + p->tfirst, p->tcount);
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
        double grow = 2.0 * p->dev * stretch * (double)v->focal * dmax;
        n = hull_draw(r, v, pv, p->vcount, fidx, fstart, flen, p->tcount, front, grow, n);
    }
    render_shrunk_batch(r, v, n);
    if (cp->rest_count)
        render_mesh_shrunk(r, s->scene, v, mesh, xf, cp->rest, cp->rest_count);
}

uint32_t sl_occ_raster_render(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const uint32_t *proxies,
                              uint32_t n)
{
    size_t k = 0;
    uint32_t rendered = 0;
    const struct sl_scene_t *sc = s->scene;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t p = proxies[i];
        if (r->stamp[p] == r->frame_id)
            continue;
        r->stamp[p] = r->frame_id;
        const sl_occ_proxy *pr = &s->proxies[p];
        rendered++;
        r->triangles_rendered += pr->triangles;
        if (pr->kind == SL_OCC_PRISM && r->erode) {
            if (r->hull)
                render_prism_hull(r, s, v, pr);
            else
                render_prism_eroded(r, s, v, pr);
            continue;
        }
        if (pr->kind == SL_OCC_PRISM) {
            size_t m = 3 * (size_t)pr->count;
            memcpy(r->batch + k, s->prism_idx + 3 * (size_t)pr->first, m * sizeof(uint32_t));
            k += m;
            continue;
        }
        if (pr->kind == SL_OCC_MESH && r->hull)
            render_mesh_hull(r, s, v, pr->mesh, object_transform(sc, pr->object));
        else if (pr->kind == SL_OCC_MESH)
            render_mesh_shrunk(r, sc, v, pr->mesh, object_transform(sc, pr->object), NULL, 0);
        else if (r->hull)
            render_mesh_hull(r, s, v, pr->mesh, sl_scene_occluder(s->scene, pr->source).transform);
        else if (r->erode)
            render_mesh_shrunk(r, sc, v, pr->mesh, sl_scene_occluder(s->scene, pr->source).transform, NULL, 0);
        else
            render_mesh(r, sc, v, pr->mesh, sl_scene_occluder(s->scene, pr->source).transform);
    }
    if (k) {
        /* prisms are closed and the eye is outside them (sl_occ_usable): back faces are hidden */
        (void)sl_raster_render_triangles(r->ctx, s->prism_pos, s->prism_vertex_count, r->batch, (uint32_t)(k / 3), 12,
                                         v->vp.m, SL_RASTER_CULL_CW, NULL);
        if (r->rec)
            sl_occ_recorder_batch(r->rec, s->prism_pos, 12, r->batch, (uint32_t)(k / 3), v->vp.m, SL_RASTER_CULL_CW);
    }
    r->occluders_rendered += rendered;
    return rendered;
}

sl_raster_result sl_occ_raster_test(sl_occ_raster *r, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d)
{
    r->queries++;
    if (x1 > x0 && y1 > y0)
        r->pixel_queries += (uint64_t)(x1 - x0) * (uint64_t)(y1 - y0);
    sl_raster_result res = sl_raster_test_rect(r->ctx, x0, y0, x1, y1, d);
    if (r->rec)
        sl_occ_recorder_query(r->rec, x0, y0, x1, y1, d, res);
    return res;
}

sl_raster_result sl_occ_raster_test_object(sl_occ_raster *r, sl_scene scene, const sl_occ_view *v, uint32_t object)
{
    object_mesh om = get_object_mesh(scene, object);
    float m[16];
    mul_affine(&v->vp, &om.xf, m);
    r->queries++;
    sl_raster_result res = sl_raster_test_triangles(r->ctx, om.pos, om.mr->vertex_count, om.idx,
                                                    om.mr->triangle_count, 12, m, SL_RASTER_CULL_NONE);
    if (r->rec)
        sl_occ_recorder_mesh_query(r->rec, om.pos, 12, om.idx, om.mr->triangle_count, m, SL_RASTER_CULL_NONE, res);
    return res;
}

/* One sampled test (sl_occ_test_object_sampled): the layers, the rectangle, and per pixel of it
 * the nearest depth already proven hidden (-infinity: none). */
/* Reversed depth of a clip-space point exactly as the oracle computes a vertex's (raster_ref.c). */
static inline double oracle_depth(const double c[4])
{
    double inv = 1.0 / c[3];
    double d = 0.5 * (1.0 - c[2] * inv);
    return d < 0 ? 0 : d > 1 ? 1 : d;
}

typedef struct sampled_test {
    sl_occ_raster *const *layers;
    uint32_t layer_count;
    sl_occ_exact *exact;
    /* the current triangle's oracle depth bound, computed when first needed (rd < 0: not yet) */
    double rd, mex[16];
    const float *tri[3];
    int32_t x0, y0, w, h;
    float *proven;
} sampled_test;

/* Is every pixel of [x0, x1) x [y0, y1) hidden at depth d in one layer? The rasterizer's rectangle
 * test is monotone in the pixel set (a subtile that hides a set of pixels hides each subset), so a
 * rectangle hidden in a layer proves each of its pixels hidden there: the per-pixel answers below
 * are unchanged, only fewer queries are made. */
static bool rect_hidden(sampled_test *t, int32_t x0, int32_t y0, int32_t x1, int32_t y1, float d)
{
    for (uint32_t l = 0; l < t->layer_count; l++)
        if (t->layers[l]->occluders_rendered &&
            sl_occ_raster_test(t->layers[l], x0, y0, x1, y1, d) != SL_RASTER_VISIBLE)
            return true;
    return false;
}

/* Is pixel (x, y) hidden at depth d (oracle depth rd) in some layer or in the exact layer?
 * Remembers the layers' answers (the exact layer's are in the oracle's depth order, which d does
 * not follow exactly). */
static bool sample_hidden(sampled_test *t, int32_t x, int32_t y, float d)
{
    float *p = t->proven + (size_t)(y - t->y0) * (size_t)t->w + (size_t)(x - t->x0);
    if (d <= *p)
        return true; /* hidden at a nearer depth already */
    if (t->exact && t->exact->drawn) {
        if (t->rd < 0.0) {
            /* the triangle's largest vertex depth as the oracle computes it (its fragments'
             * depths are clamped to the vertices' range) */
            double best = 0.0;
            for (int j = 0; j < 3; j++) {
                const float *q = t->tri[j];
                const double *mx = t->mex;
                double cl[4];
                for (int row = 0; row < 4; row++)
                    cl[row] = mx[row] * q[0] + mx[4 + row] * q[1] + mx[8 + row] * q[2] + mx[12 + row];
                double od = cl[3] > 0.0 ? oracle_depth(cl) : INFINITY;
                best = od > best ? od : best;
            }
            t->rd = best;
        }
        if (sl_occ_exact_hides(t->exact, x, y, t->rd))
            return true;
    }
    if (!rect_hidden(t, x, y, x + 1, y + 1, d))
        return false;
    *p = d;
    return true;
}

/* Test the pixel centres of the rectangle that lie within SL_OCC_MIN_INSET_PX of triangle (a, b,
 * c) (screen positions) at depth d; false at the first one not hidden. The margin covers the
 * oracle's 1/256-pixel vertex snapping (a snapped triangle lies within half a snapping step of the
 * exact one) and the rounding of this projection many times over; a triangle whose area is too
 * small for stable edge functions tests every centre of its grown bounding box. */
static bool sample_triangle(sampled_test *t, const double *a, const double *b, const double *c, float d)
{
    const double eps = SL_OCC_MIN_INSET_PX;
    double lx = a[0] < b[0] ? a[0] : b[0], hx = a[0] < b[0] ? b[0] : a[0];
    double ly = a[1] < b[1] ? a[1] : b[1], hy = a[1] < b[1] ? b[1] : a[1];
    lx = c[0] < lx ? c[0] : lx;
    hx = c[0] > hx ? c[0] : hx;
    ly = c[1] < ly ? c[1] : ly;
    hy = c[1] > hy ? c[1] : hy;
    /* the centres px + 0.5 in [lx - eps, hx + eps], clamped to the rectangle */
    double fx0 = ceil(lx - eps - 0.5), fx1 = floor(hx + eps - 0.5), fy0 = ceil(ly - eps - 0.5),
           fy1 = floor(hy + eps - 0.5);
    fx0 = fx0 > (double)t->x0 ? fx0 : (double)t->x0;
    fy0 = fy0 > (double)t->y0 ? fy0 : (double)t->y0;
    fx1 = fx1 < (double)(t->x0 + t->w - 1) ? fx1 : (double)(t->x0 + t->w - 1);
    fy1 = fy1 < (double)(t->y0 + t->h - 1) ? fy1 : (double)(t->y0 + t->h - 1);
    if (!(fx0 <= fx1) || !(fy0 <= fy1))
        return true;
    double area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    const double *v[3] = {a, b, c};
    double ex[3] = {0, 0, 0}, ey[3] = {0, 0, 0}, lim[3] = {0, 0, 0};
    bool thin = !(fabs(area2) > 1e-6);
    double sgn = area2 < 0 ? -1.0 : 1.0;
    for (int i = 0; i < 3 && !thin; i++) {
        const double *p = v[i], *q = v[(i + 1) % 3];
        ex[i] = sgn * (q[0] - p[0]);
        ey[i] = sgn * (q[1] - p[1]);
        /* inside or within eps: cross(e, s - p) >= -eps |e| (edges counter-clockwise) */
        lim[i] = -eps * sqrt(ex[i] * ex[i] + ey[i] * ey[i]) + ex[i] * p[1] - ey[i] * p[0];
    }
    /* one query for the centres' bounding rectangle, then one per row's span of centres inside
     * (an interval: the grown triangle is convex), then pixel by pixel where those cannot tell */
    int32_t px0 = (int32_t)fx0, px1 = (int32_t)fx1, py0 = (int32_t)fy0, py1 = (int32_t)fy1;
    if ((px1 > px0 || py1 > py0) && rect_hidden(t, px0, py0, px1 + 1, py1 + 1, d))
        return true;
    for (int32_t y = py0; y <= py1; y++) {
        double sy = y + 0.5;
        int32_t lo = px1 + 1, hi = px0 - 1;
        for (int32_t x = px0; x <= px1; x++) {
            double sx = x + 0.5;
            if (thin || (ex[0] * sy - ey[0] * sx >= lim[0] && ex[1] * sy - ey[1] * sx >= lim[1] &&
                         ex[2] * sy - ey[2] * sx >= lim[2])) {
                lo = x < lo ? x : lo;
                hi = x;
            }
        }
        if (hi > lo && py1 > py0 && rect_hidden(t, lo, y, hi + 1, y + 1, d))
            continue;
        for (int32_t x = lo; x <= hi; x++)
            if (!sample_hidden(t, x, y, d))
                return false;
    }
    return true;
}

sl_raster_result sl_occ_test_object_sampled(sl_occ_raster *const *layers, uint32_t layer_count,
                                            struct sl_occ_exact *exact, sl_scene scene, const sl_occ_view *v,
                                            uint32_t object, const sl_occ_rect *rect)
{
    int32_t w = rect->x1 - rect->x0, h = rect->y1 - rect->y0;
    if (w <= 0 || h <= 0 || (int64_t)w * h > SL_OCC_SAMPLED_MAX_PX || layer_count == 0)
        return SL_RASTER_VISIBLE;
    object_mesh om = get_object_mesh(scene, object);
    const sl_mesh_rec *mr = om.mr;
    const float *pos = om.pos;
    const uint32_t *idx = om.idx;
    double m[16];
    mul_affine_d(&v->vp, &om.xf, m);
    float proven[SL_OCC_SAMPLED_MAX_PX];
    for (int32_t i = 0; i < w * h; i++)
        proven[i] = -INFINITY;
    sampled_test t = {.layers = layers, .layer_count = layer_count, .exact = exact, .rd = -1.0,
                      .x0 = rect->x0, .y0 = rect->y0, .w = w, .h = h, .proven = proven};
    if (exact && exact->drawn)
        sl_refrast_compose(exact->vp, &om.xf, t.mex); /* the oracle's object-to-clip matrix */
    sl_occ_screen_vertex cache[SAMPLED_VERTEX_CACHE];
    bool have[SAMPLED_VERTEX_CACHE];
    bool cached = mr->vertex_count <= SAMPLED_VERTEX_CACHE;
    if (cached)
        memset(have, 0, mr->vertex_count * sizeof have[0]);
    layers[0]->queries++;
    for (uint32_t k = 0; k < mr->triangle_count; k++) {
        sl_occ_screen_vertex own[3];
        const sl_occ_screen_vertex *tv[3]; /* pointers: no copies of the cached vertices */
        for (int j = 0; j < 3; j++) {
            uint32_t vi = idx[3 * k + (uint32_t)j];
            if (vi >= mr->vertex_count)
                return SL_RASTER_VISIBLE;
            if (!cached) {
                own[j] = project_vertex(v, m, pos + 3 * (size_t)vi);
                tv[j] = &own[j];
            } else {
                if (!have[vi]) {
                    cache[vi] = project_vertex(v, m, pos + 3 * (size_t)vi);
                    have[vi] = true;
                }
                tv[j] = &cache[vi];
            }
            if (!tv[j]->ok)
                return SL_RASTER_VISIBLE;
        }
        /* the triangle's nearest depth, nudged nearer like a box's nearest corner */
        float dmax = sl_occ_maxf(tv[0]->d, sl_occ_maxf(tv[1]->d, tv[2]->d));
        dmax += fabsf(dmax) * SL_MARGIN_REL_F;
        t.rd = -1.0;
        for (int j = 0; j < 3; j++)
            t.tri[j] = pos + 3 * (size_t)idx[3 * k + (uint32_t)j];
        const double a[2] = {tv[0]->x, tv[0]->y}, b[2] = {tv[1]->x, tv[1]->y}, c[2] = {tv[2]->x, tv[2]->y};
        if (!sample_triangle(&t, a, b, c, dmax))
            return SL_RASTER_VISIBLE;
    }
    return SL_RASTER_OCCLUDED;
}

/* x extent of the convex polygon h (m vertices) within the band ya <= y <= yb: false when the band
 * misses it. */
static bool band_extent(const double *h, uint32_t m, double ya, double yb, double *xl, double *xr)
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

bool sl_occ_box_rows_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact,
                            const sl_occ_view *v, const sl_aabb *box, const sl_occ_rect *r, uint32_t max_rows)
{
    /* the corners of the box grown by 2^-20 of its coordinates (object boxes are computed in
     * float, the oracle places vertices in double), projected in double with the oracle's matrix
     * (a float projection of world coordinates errs by up to a tenth of a pixel near the eye) */
    double xy[16];
    const double W = (double)v->width, H = (double)v->height;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? grow_coord(box->max.x, 1) : grow_coord(box->min.x, -1),
                       (k & 2) ? grow_coord(box->max.y, 1) : grow_coord(box->min.y, -1),
                       (k & 4) ? grow_coord(box->max.z, 1) : grow_coord(box->min.z, -1)};
        double c[4];
        for (int row = 0; row < 4; row++)
            c[row] = (double)v->vp.m[row] * p[0] + (double)v->vp.m[4 + row] * p[1] + (double)v->vp.m[8 + row] * p[2] +
                     (double)v->vp.m[12 + row];
        if (!(c[3] > 0.0) || !isfinite(c[0]) || !isfinite(c[1]))
            return false;
        xy[2 * k] = (c[0] / c[3] + 1.0) * 0.5 * W;
        xy[2 * k + 1] = (1.0 - c[1] / c[3]) * 0.5 * H;
    }
    /* pixel centres within 1/64 pixel of the silhouette count as covered: the oracle's vertex
     * snapping moves edges by at most 1/512 pixel */
    const double eps = SL_MARGIN_CENTRE_PX;
    /* first the rectangle of the pixel centres the corners' bounding box covers: it leaves out the
     * border rows and columns the box touches without covering a centre (one query) */
    double lx = xy[0], hx = xy[0], ly = xy[1], hy = xy[1];
    for (int k = 1; k < 8; k++) {
        lx = xy[2 * k] < lx ? xy[2 * k] : lx;
        hx = xy[2 * k] > hx ? xy[2 * k] : hx;
        ly = xy[2 * k + 1] < ly ? xy[2 * k + 1] : ly;
        hy = xy[2 * k + 1] > hy ? xy[2 * k + 1] : hy;
    }
    double cx0 = ceil(lx - eps - 0.5), cx1 = floor(hx + eps - 0.5);
    double cy0 = ceil(ly - eps - 0.5), cy1 = floor(hy + eps - 0.5);
    cx0 = cx0 > r->x0 ? cx0 : r->x0;
    cy0 = cy0 > r->y0 ? cy0 : r->y0;
    cx1 = cx1 < r->x1 - 1 ? cx1 : r->x1 - 1;
    cy1 = cy1 < r->y1 - 1 ? cy1 : r->y1 - 1;
    if (cx0 > cx1 || cy0 > cy1)
        return true; /* no pixel centre at all */
    for (uint32_t l = 0; l < layer_count; l++)
        if (layers[l]->occluders_rendered &&
            sl_occ_raster_test(layers[l], (int32_t)cx0, (int32_t)cy0, (int32_t)cx1 + 1, (int32_t)cy1 + 1, r->dnear) !=
                SL_RASTER_VISIBLE)
            return true;
    if ((uint32_t)(r->y1 - r->y0) > max_rows)
        return false;
    double rd = -1.0; /* the box's largest oracle depth, computed when first needed */
    double h[16];
    uint32_t m = sl_convex_hull8(xy, 8, h);
    int32_t y = r->y0;
    while (y < r->y1) {
        /* one query per group of rows inside one 4-row band of subtiles: the union of the rows'
         * spans (the rectangle test is monotone, so a hidden union hides each row) */
        int32_t yend = ((y >> 2) + 1) << 2;
        if (yend > r->y1)
            yend = r->y1;
        int32_t qx0 = INT32_MAX, qx1 = INT32_MIN, qy0 = INT32_MAX, qy1 = INT32_MIN;
        int32_t span[4][2], npx = 0;
        for (int32_t row = y; row < yend; row++) {
            span[row - y][0] = 0;
            span[row - y][1] = -1;
            double yc = row + 0.5, xl, xr;
            if (!band_extent(h, m, yc - eps, yc + eps, &xl, &xr))
                continue;
            /* columns whose centre c + 0.5 lies in [xl - eps, xr + eps] */
            double ca = ceil(xl - eps - 0.5), cb = floor(xr + eps - 0.5);
            ca = fmax(ca, r->x0);
            cb = fmin(cb, r->x1 - 1);
            if (ca > cb)
                continue;
            span[row - y][0] = (int32_t)ca;
            span[row - y][1] = (int32_t)cb;
            npx += (int32_t)(cb - ca) + 1;
            qx0 = qx0 < (int32_t)ca ? qx0 : (int32_t)ca;
            qx1 = qx1 > (int32_t)cb + 1 ? qx1 : (int32_t)cb + 1;
            qy0 = qy0 < row ? qy0 : row;
            qy1 = row + 1;
        }
        if (qx0 < qx1) {
            bool hid = false;
            for (uint32_t l = 0; l < layer_count && !hid; l++)
                hid = layers[l]->occluders_rendered &&
                      sl_occ_raster_test(layers[l], qx0, qy0, qx1, qy1, r->dnear) != SL_RASTER_VISIBLE;
            /* pixel by pixel: each centre hidden in some layer or in the exact layer */
            for (int32_t row = y; row < yend && !hid && npx <= 64; row++)
                for (int32_t x = span[row - y][0]; x <= span[row - y][1]; x++) {
                    if (rd < 0.0)
                        rd = exact && exact->drawn ? sl_occ_exact_box_depth(exact, box) : INFINITY;
                    bool ph = sl_occ_exact_hides(exact, x, row, rd);
                    for (uint32_t l = 0; l < layer_count && !ph; l++)
                        ph = layers[l]->occluders_rendered &&
                             sl_occ_raster_test(layers[l], x, row, x + 1, row + 1, r->dnear) != SL_RASTER_VISIBLE;
                    if (!ph)
                        return false;
                }
            if (!hid && npx > 64)
                return false;
        }
        y = yend;
    }
    return true;
}

bool sl_occ_object_hidden(sl_occ_raster *const *layers, uint32_t layer_count, sl_occ_exact *exact, sl_scene scene,
                          const sl_occ_view *v, uint32_t object, const sl_aabb *box, const sl_occ_mesh_tests *t,
                          uint64_t *tests)
{
    const struct sl_scene_t *sc = scene;
    uint32_t tris = sl_scene_meshes(sc)[sl_scene_objects(sc)[object].mesh].triangle_count;
    if ((tris > t->mesh_test && tris > t->sample_tris) || sl_occ_point_in_box(v->eye, box, 0.0f))
        return false;
    if (tests)
        (*tests)++;
    /* the object is hidden when either test hides it; the pixel-centre test goes first (cheaper,
     * and it answers most small objects) */
    sl_occ_rect r;
    if (tris <= t->sample_tris && sl_occ_project_box(v, box, &r) == SL_OCC_RECT &&
        (int64_t)(r.x1 - r.x0) * (r.y1 - r.y0) <= t->sample_px &&
        sl_occ_test_object_sampled(layers, layer_count, exact, scene, v, object, &r) != SL_RASTER_VISIBLE)
        return true;
    if (tris <= t->mesh_test)
        for (uint32_t l = 0; l < layer_count; l++)
            if (layers[l]->occluders_rendered &&
                sl_occ_raster_test_object(layers[l], scene, v, object) != SL_RASTER_VISIBLE)
                return true;
    return false;
}

/* ---- the exact layer ---- */

sl_status sl_occ_exact_init(sl_occ_exact *e, const sl_allocator *alloc, sl_error *err)
{
    (void)err;
    memset(e, 0, sizeof *e);
    e->alloc = *alloc;
    return SL_OK;
}

void sl_occ_exact_free(sl_occ_exact *e)
{
    size_t n = (size_t)e->width * e->height;
    sl_free(&e->alloc, e->depth, n * sizeof(float));
    sl_free(&e->alloc, e->ids, n * sizeof(uint32_t));
    sl_free(&e->alloc, e->dirty, e->dirty_cap * sizeof *e->dirty);
    sl_refrast_scratch_free(&e->alloc, &e->scratch);
    memset(e, 0, sizeof *e);
}

sl_status sl_occ_exact_begin(sl_occ_exact *e, const sl_occ_view *v, sl_error *err)
{
    if (e->width != v->width || e->height != v->height) {
        size_t old = (size_t)e->width * e->height, n = (size_t)v->width * v->height;
        sl_free(&e->alloc, e->depth, old * sizeof(float));
        sl_free(&e->alloc, e->ids, old * sizeof(uint32_t));
        e->depth = sl_calloc(&e->alloc, n, sizeof(float));
        e->ids = sl_alloc(&e->alloc, n * sizeof(uint32_t));
        e->width = e->height = 0;
        if (!e->depth || !e->ids) {
            sl_free(&e->alloc, e->depth, n * sizeof(float));
            sl_free(&e->alloc, e->ids, n * sizeof(uint32_t));
            e->depth = NULL;
            e->ids = NULL;
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "exact layer: out of memory for %ux%u pixels", v->width,
                           v->height);
        }
        for (size_t i = 0; i < n; i++)
            e->ids[i] = SL_NONE;
        e->width = v->width;
        e->height = v->height;
        e->dirty_count = 0;
    }
    /* clear what the last frame drew (depth 0 and no id: what sl_refrast_clear writes) */
    for (size_t k = 0; k < e->dirty_count; k++) {
        const sl_occ_rect *r = &e->dirty[k];
        for (int32_t y = r->y0; y < r->y1; y++) {
            size_t at = (size_t)y * e->width + (size_t)r->x0, n = (size_t)(r->x1 - r->x0);
            memset(e->depth + at, 0, n * sizeof(float));
            for (size_t i = 0; i < n; i++)
                e->ids[at + i] = SL_NONE;
        }
    }
    e->dirty_count = 0;
    e->drawn = 0;
    e->pixel_tests = 0;
    for (int i = 0; i < 16; i++)
        e->vp[i] = (double)v->vp.m[i]; /* as the oracle converts sl_camera_view_proj */
    return SL_OK;
}

double sl_occ_exact_box_depth(const sl_occ_exact *e, const sl_aabb *b)
{
    double best = 0.0;
    for (int k = 0; k < 8; k++) {
        double p[3] = {(k & 1) ? grow_coord(b->max.x, 1) : grow_coord(b->min.x, -1),
                       (k & 2) ? grow_coord(b->max.y, 1) : grow_coord(b->min.y, -1),
                       (k & 4) ? grow_coord(b->max.z, 1) : grow_coord(b->min.z, -1)};
        double c[4];
        for (int row = 0; row < 4; row++)
            c[row] = e->vp[row] * p[0] + e->vp[4 + row] * p[1] + e->vp[8 + row] * p[2] + e->vp[12 + row];
        if (!(c[3] > 0.0))
            return INFINITY;
        double od = oracle_depth(c);
        best = od > best ? od : best;
    }
    return best;
}

sl_status sl_occ_exact_draw(sl_occ_exact *e, sl_scene scene, uint32_t object, const sl_occ_rect *r, sl_error *err)
{
    const struct sl_scene_t *sc = scene;
    object_mesh om = get_object_mesh(sc, object);
    if (!sl_refrast_scratch_reserve(&e->alloc, &e->scratch, om.mr->vertex_count))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "exact layer: out of memory for %u vertices", om.mr->vertex_count);
    if (e->dirty_count == e->dirty_cap) {
        size_t cap = e->dirty_cap ? 2 * e->dirty_cap : 256;
        sl_occ_rect *d = sl_alloc(&e->alloc, cap * sizeof *d);
        if (!d)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "exact layer: out of memory");
        if (e->dirty_count)
            memcpy(d, e->dirty, e->dirty_count * sizeof *d);
        sl_free(&e->alloc, e->dirty, e->dirty_cap * sizeof *d);
        e->dirty = d;
        e->dirty_cap = cap;
    }
    /* what the oracle draws for the object: its matrix, mesh and facing rule (a closed convex
     * mesh without its back faces; drawing fewer fragments than the oracle is always safe) */
    double m[16];
    sl_refrast_compose(e->vp, &om.xf, m);
    sl_refrast_cull cull = SL_REFRAST_CULL_NONE;
    if (sl_scene_objects(sc)[object].flags & SL_OBJECT_CLOSED_CONVEX) {
        const float *a = om.xf.m;
        double det = (double)a[0] * ((double)a[5] * a[10] - (double)a[6] * a[9]) -
                     (double)a[1] * ((double)a[4] * a[10] - (double)a[6] * a[8]) +
                     (double)a[2] * ((double)a[4] * a[9] - (double)a[5] * a[8]);
        cull = det < 0 ? SL_REFRAST_CULL_FRONT : SL_REFRAST_CULL_BACK;
    }
    sl_refrast_target t = {e->width, e->height, e->ids, e->depth, NULL, 2.0 * SL_REFRAST_GUARD_PX / e->width,
                           2.0 * SL_REFRAST_GUARD_PX / e->height};
    sl_refrast_mesh(&t, &e->scratch, m, om.pos, om.mr->vertex_count, om.idx, om.mr->triangle_count, object, cull);
    e->dirty[e->dirty_count++] = *r;
    e->drawn++;
    return SL_OK;
}

sl_status sl_occ_raster_end(sl_occ_raster *r, const sl_occ_levels *levels, sl_error *err)
{
    bool debug = r->frame == r->debug_frame;
    r->frame++;
    if (!debug)
        return SL_OK;
    sl_status st = SL_OK;
    if (r->rec) {
        st = sl_occ_recorder_save(r->rec, r->record, err);
        sl_occ_recorder_destroy(r->rec);
        r->rec = NULL;
        if (st != SL_OK)
            return st;
    }
    if (r->dump) {
        char path[300];
        size_t n = (size_t)r->width * r->height;
        float *depth = sl_alloc(&r->alloc, n * sizeof(float));
        if (!depth)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "dump: out of memory for %zu depths", n);
        st = sl_raster_read_depth(r->ctx, depth, n, err);
        snprintf(path, sizeof path, "%s-depth.png", r->dump);
        if (st == SL_OK)
            st = sl_occ_write_depth_png(path, depth, r->width, r->height, &r->alloc, err);
        sl_free(&r->alloc, depth, n * sizeof(float));
        if (st == SL_OK && levels && levels->count) {
            snprintf(path, sizeof path, "%s-pyramid.png", r->dump);
            st = sl_occ_write_levels_png(path, levels, &r->alloc, err);
        }
    }
    return st;
}

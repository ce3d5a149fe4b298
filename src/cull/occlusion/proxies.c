/* Occluder proxies: prisms from footprints shrunk inward, MESH and SCENE_MESH proxies, their
 * faces, refresh on scene change, and whether a proxy may be used for a view (proxies.h). The
 * polygon geometry the prisms need is in core/polygon.c. */
#include "proxies.h"
#include "options.h"

#include "core/polygon.h"

#include <float.h>
#include <math.h>

/* ---- prisms: footprint polygons shrunk inward ---- */


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
static sl_status add_prism(sl_occ_set *s, build_ctx *b, uint32_t fi, sl_dvec2 *work_p, sl_dvec2 *work_q, uint32_t *work_i,
                           uint32_t *tri, uint32_t *polys, uint32_t *plen, sl_vec3 *work_v, sl_error *err)
{
    sl_footprint_view fp = sl_scene_footprint(s->scene, fi);
    uint32_t n = fp.vertex_count;
    if (n < 3 || n > 512)
        return SL_OK;
    if (fp.object != SL_NONE && fp.object >= s->object_count)
        return SL_OK;
    /* a DYNAMIC object's footprint stays where it was placed while the object moves: never a
     * prism (the object occludes by its own mesh, at its current transform) */
    if (fp.object != SL_NONE && (sl_scene_objects(s->scene)[fp.object].flags & SL_OBJECT_DYNAMIC))
        return SL_OK;
    for (uint32_t i = 0; i < n; i++)
        work_p[i] = (sl_dvec2){fp.xy[2 * i], fp.xy[2 * i + 1]};
    /* the largest inset up to the option that can be certified, halving down to 1 cm */
    double d = s->opt.inset;
    if (s->opt.screen_margin) {
        /* hook (SL_OCC_THIN_INSET): drawn by its eroded silhouette, a prism's inset need only pass
         * the float check below; a thin one is raised to what the coordinates need (the shrunk
         * polygon lies in the footprint's box, so the footprint's coordinates bound its own) */
        double mc = fmax(fabs((double)fp.roof_z), fabs((double)fp.base_z));
        for (uint32_t i = 0; i < 2 * n; i++)
            mc = fmax(mc, fabs((double)fp.xy[i]));
        d = fmax(d, 1.01 * 16.0 * FLT_EPSILON * mc);
    }
    bool ok = false;
    while (!ok && d >= 0.01 - 1e-9) {
        ok = (double)fp.roof_z - fp.base_z > 2 * d + 0.01 && sl_inset_polygon(work_p, n, d, work_q) &&
             sl_ear_clip(work_q, n, work_i, tri);
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
    sl_merge_convex(work_q, n, tri, polys, plen);
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
    sl_dvec2 *wp = NULL, *wq = NULL;
    uint32_t *wi = NULL, *tri = NULL, *polys = NULL, *plen = NULL;
    sl_vec3 *wv = NULL;
    uint32_t maxn = 3;
    uint32_t nf = sl_scene_footprint_count(scene);
    for (uint32_t i = 0; i < nf; i++) {
        uint32_t n = sl_scene_footprint(scene, i).vertex_count;
        if (n <= 512)
            maxn = SL_MAX(maxn, n);
    }
    wp = sl_alloc(alloc, maxn * sizeof(sl_dvec2));
    wq = sl_alloc(alloc, maxn * sizeof(sl_dvec2));
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
        if ((!(objects[o].flags & SL_OBJECT_OCCLUDER) && !s->opt.all_objects) || s->object_proxy[o] != SL_NONE ||
            (objects[o].flags & SL_OBJECT_SEE_THROUGH)) /* see-through never occludes, all_objects or not */
            continue;
        sl_affine id = sl_affine_identity();
        const sl_affine *xf = objects[o].transform == SL_NONE ? &id : &xfs[objects[o].transform];
        st = add_mesh_proxy(s, &b, SL_OCC_MESH, objects[o].mesh, xf, o, SL_NONE,
                            s->opt.faces && !(objects[o].flags & SL_OBJECT_DYNAMIC), err);
    }
    /* 3. the scene's 3D occluder meshes (static, trusted to lie inside their objects); one with an
     * object is that object's proxy when it has none yet (the walks reach proxies through objects),
     * and is used only while the eye is outside the object's box (sl_occ_usable) */
    uint32_t no = sl_scene_occluder_count(scene);
    for (uint32_t i = 0; i < no && st == SL_OK; i++) {
        sl_occluder_view ov = sl_scene_occluder(scene, i);
        uint32_t owner = ov.object < s->object_count ? ov.object : SL_NONE;
        st = add_mesh_proxy(s, &b, SL_OCC_SCENE_MESH, ov.mesh, &ov.transform, owner, i, s->opt.faces, err);
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
    sl_free(alloc, wp, maxn * sizeof(sl_dvec2));
    sl_free(alloc, wq, maxn * sizeof(sl_dvec2));
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
        /* a prism or a scene occluder stands for its object where the object was: once the
         * object moves, it stands for nothing */
        if ((pr->kind != SL_OCC_PRISM && pr->kind != SL_OCC_SCENE_MESH) || pr->object == SL_NONE || !pr->enabled)
            continue;
        sl_affine now = objects[pr->object].transform != SL_NONE ? xfs[objects[pr->object].transform]
                                                                 : sl_affine_identity();
        if (memcmp(&now, &s->prism_xf[p], sizeof now) != 0)
            pr->enabled = false; /* the object moved off its footprint or boxes: never trust them again */
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
        /* a scene occluder stands inside its object's surface closed by a cap in the plane of the
         * object's lowest z at most (sl_synth_occluders: a building without a floor): it hides
         * what the surface hides only from above that plane */
        if (p->kind == SL_OCC_SCENE_MESH && !(v->eye.z > ob.min.z + g))
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

bool sl_occ_applicable(sl_scene scene, const void *config, char *why, size_t why_size)
{
    const sl_occ_common *c = config; /* every occlusion method's config starts with its sl_occ_common */
    if (c->all_objects || sl_scene_footprint_count(scene) || sl_scene_occluder_count(scene))
        return true;
    const sl_object_rec *objects = sl_scene_objects(scene);
    uint32_t n = sl_scene_object_count(scene);
    for (uint32_t o = 0; o < n; o++)
        if ((objects[o].flags & SL_OBJECT_OCCLUDER) && !(objects[o].flags & SL_OBJECT_SEE_THROUGH))
            return true;
    snprintf(why, why_size,
             "the scene has no occluders (no building footprints, no occluder meshes, no object flagged as an "
             "occluder): `sightline occluders` synthesises them for an imported model, or all_objects=true lets "
             "every object's mesh occlude");
    return false;
}

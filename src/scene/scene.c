/* The scene model: meshes, objects, occluders, terrain, streets, BSP data, metadata.
 * See include/sightline/scene.h for the contract. */
#include "scene_internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>

#define ARR(s, name) (&(s)->name)
#define A(s) (&(s)->alloc)

const char *sl_object_kind_name(uint32_t kind)
{
    static const char *names[SL_KIND_COUNT] = {"other", "building", "ground", "car", "tree",
                                               "lamp", "bsp-faces", "water", "imported"};
    return kind < SL_KIND_COUNT ? names[kind] : "unknown";
}

sl_status sl_scene_create(const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_create: out is NULL");
    alloc = sl_alloc_or_default(alloc);
    struct sl_scene_t *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_create: out of memory");
    s->alloc = *alloc;
    *out = s;
    return SL_OK;
}

void sl_scene_destroy(sl_scene s)
{
    if (!s)
        return;
    sl_allocator alloc = s->alloc;
    const sl_allocator *a = &alloc;
    sl_array_free(a, &s->meshes, sizeof(sl_mesh_rec));
    sl_array_free(a, &s->positions, sizeof(float));
    sl_array_free(a, &s->normals, sizeof(float));
    sl_array_free(a, &s->indices, sizeof(uint32_t));
    sl_array_free(a, &s->objects, sizeof(sl_object_rec));
    sl_array_free(a, &s->bounds, sizeof(sl_aabb));
    sl_array_free(a, &s->transforms, sizeof(sl_affine));
    sl_array_free(a, &s->footprints, sizeof(sl_footprint_rec));
    sl_array_free(a, &s->footprint_xy, sizeof(float));
    sl_array_free(a, &s->occluders, sizeof(sl_occluder_rec));
    sl_array_free(a, &s->terrain_heights, sizeof(float));
    sl_array_free(a, &s->street_polys, sizeof(sl_polygon_rec));
    sl_array_free(a, &s->street_xy, sizeof(float));
    sl_array_free(a, &s->street_nodes, sizeof(sl_street_node));
    sl_array_free(a, &s->street_edges, sizeof(sl_street_edge));
    sl_array_free(a, &s->bsp_planes, sizeof(sl_plane));
    sl_array_free(a, &s->bsp_nodes, sizeof(sl_bsp_node));
    sl_array_free(a, &s->bsp_leaves, sizeof(sl_bsp_leaf));
    sl_array_free(a, &s->bsp_leaf_objects, sizeof(uint32_t));
    sl_array_free(a, &s->bsp_pvs, 1);
    for (size_t i = 0; i < s->meta.count; i++) {
        sl_meta_rec *m = &SL_AT(s->meta, sl_meta_rec, i);
        sl_strfree(a, m->key);
        sl_strfree(a, m->value);
    }
    sl_array_free(a, &s->meta, sizeof(sl_meta_rec));
    sl_array_free(a, &s->materials, sizeof(sl_material_rec));
    sl_array_free(a, &s->material_text, 1);
    sl_array_free(a, &s->object_materials, sizeof(uint32_t));
    sl_array_free(a, &s->uvs, sizeof(float));
    sl_array_free(a, &s->mesh_uvs, 1);
    sl_scene_names_free(s);
    sl_scene_levels_free(s);
    sl_scene_motions_free(s);
    sl_strfree(a, s->base_dir);
    sl_file_unmap(&s->mapping);
    sl_free(a, s, sizeof *s);
}

/* ---- building ---- */

static void compute_normals(const float *p, const uint32_t *idx, uint32_t nv, uint32_t nt, float *n)
{
    memset(n, 0, (size_t)nv * 3 * sizeof(float));
    /* area-weighted: the unnormalised cross product carries twice the triangle's area */
    for (uint32_t t = 0; t < nt; t++) {
        const float *a = p + 3 * idx[3 * t], *b = p + 3 * idx[3 * t + 1], *c = p + 3 * idx[3 * t + 2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++)
                n[3 * idx[3 * t + k] + j] += cr[j];
    }
    for (uint32_t v = 0; v < nv; v++) {
        float *q = n + 3 * v;
        float l = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (l > 0) {
            q[0] /= l, q[1] /= l, q[2] /= l;
        } else {
            q[0] = 0, q[1] = 0, q[2] = 1;
        }
    }
}

sl_status sl_scene_add_mesh(sl_scene s, const sl_mesh_desc *d, uint32_t *out_mesh, sl_error *err)
{
    if (!s || !d || (d->vertex_count && !d->positions) || (d->triangle_count && !d->indices))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_mesh: NULL argument");
    if (s->meshes.count >= SL_NONE - 1)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_scene_add_mesh: too many meshes");
    sl_aabb box = sl_aabb_empty();
    for (uint32_t v = 0; v < d->vertex_count; v++) {
        const float *p = d->positions + 3 * (size_t)v;
        if (!sl_finite3(p))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "mesh vertex %u: position is not finite", v);
        if (d->normals && !sl_finite3(d->normals + 3 * (size_t)v))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "mesh vertex %u: normal is not finite", v);
        if (d->uvs && (!isfinite(d->uvs[2 * (size_t)v]) || !isfinite(d->uvs[2 * (size_t)v + 1])))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "mesh vertex %u: uv is not finite", v);
        sl_aabb_grow(&box, (sl_vec3){p[0], p[1], p[2]});
    }
    for (uint64_t i = 0; i < 3ull * d->triangle_count; i++)
        if (d->indices[i] >= d->vertex_count)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "mesh triangle %llu: index %u out of range (%u vertices)",
                           (unsigned long long)(i / 3), d->indices[i], d->vertex_count);
    const sl_allocator *a = A(s);
    size_t nv3 = 3 * (size_t)d->vertex_count;
    sl_mesh_rec rec = {s->positions.count / 3, s->indices.count, d->vertex_count, d->triangle_count, box};
    if (!sl_array_reserve(a, &s->positions, sizeof(float), nv3) || !sl_array_reserve(a, &s->normals, sizeof(float), nv3) ||
        !sl_array_reserve(a, &s->indices, sizeof(uint32_t), 3 * (size_t)d->triangle_count) ||
        !sl_array_reserve(a, &s->meshes, sizeof rec, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_add_mesh: out of memory (%u vertices)", d->vertex_count);
    /* UVs: once one mesh has them, uvs covers every vertex (zeros where a mesh has none) and
     * mesh_uvs every mesh; before that both stay empty */
    if (d->uvs || s->mesh_uvs.count) {
        size_t nv_before = s->positions.count / 3, nm = s->meshes.count;
        size_t pad_v = nv_before > s->uvs.count / 2 ? nv_before - s->uvs.count / 2 : 0;
        size_t pad_m = nm > s->mesh_uvs.count ? nm - s->mesh_uvs.count : 0;
        if (!sl_array_reserve(a, &s->uvs, sizeof(float), 2 * (pad_v + d->vertex_count)) ||
            !sl_array_reserve(a, &s->mesh_uvs, 1, pad_m + 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_add_mesh: out of memory (%u uvs)", d->vertex_count);
        sl_array_push(a, &s->uvs, sizeof(float), NULL, 2 * pad_v);
        sl_array_push(a, &s->uvs, sizeof(float), d->uvs, 2 * (size_t)d->vertex_count);
        sl_array_push(a, &s->mesh_uvs, 1, NULL, pad_m);
        uint8_t has = d->uvs ? 1 : 0;
        sl_array_push(a, &s->mesh_uvs, 1, &has, 1);
    }
    float *np = sl_array_push(a, &s->normals, sizeof(float), d->normals, nv3);
    sl_array_push(a, &s->positions, sizeof(float), d->positions, nv3);
    sl_array_push(a, &s->indices, sizeof(uint32_t), d->indices, 3 * (size_t)d->triangle_count);
    if (!d->normals)
        compute_normals(d->positions, d->indices, d->vertex_count, d->triangle_count, np);
    sl_array_push(a, &s->meshes, sizeof rec, &rec, 1);
    if (out_mesh)
        *out_mesh = (uint32_t)(s->meshes.count - 1);
    return SL_OK;
}

static bool affine_finite(const sl_affine *t)
{
    for (int i = 0; i < 12; i++)
        if (!isfinite(t->m[i]))
            return false;
    return true;
}

static bool affine_is_identity(const sl_affine *t)
{
    sl_affine id = sl_affine_identity();
    return memcmp(t->m, id.m, sizeof id.m) == 0;
}

void sl_scene_update_object_bounds(struct sl_scene_t *s, uint32_t object)
{
    const sl_object_rec *o = &sl_scene_objects(s)[object];
    const sl_aabb *mb = &sl_scene_meshes(s)[o->mesh].bounds;
    sl_aabb *dst = &SL_AT(s->bounds, sl_aabb, object);
    *dst = o->transform == SL_NONE ? *mb : sl_aabb_transform(mb, &sl_scene_transforms(s)[o->transform]);
}

sl_status sl_scene_add_object(sl_scene s, const sl_object_desc *d, uint32_t *out_object, sl_error *err)
{
    if (!s || !d)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_object: NULL argument");
    if (d->mesh >= s->meshes.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_object: mesh %u does not exist", d->mesh);
    if (s->objects.count >= SL_NONE - 1)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_scene_add_object: too many objects");
    if (d->transform && !affine_finite(d->transform))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_object: transform is not finite");
    uint32_t material = d->material == SL_NONE ? SL_MATERIAL_NONE : d->material;
    if (material > s->materials.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_object: material %u does not exist (%zu materials)",
                       material, s->materials.count);
    const sl_allocator *a = A(s);
    sl_object_rec rec = {d->mesh, d->color, d->kind, d->flags, SL_NONE, 0};
    if (material && SL_AT(s->materials, sl_material_rec, material - 1).alpha_mode != SL_ALPHA_OPAQUE)
        rec.flags |= SL_OBJECT_SEE_THROUGH;
    if (rec.flags & SL_OBJECT_SEE_THROUGH)
        rec.flags &= ~(uint32_t)SL_OBJECT_OCCLUDER; /* see-through never occludes (scene.h) */
    if (!sl_array_reserve(a, &s->objects, sizeof rec, 1) || !sl_array_reserve(a, &s->bounds, sizeof(sl_aabb), 1) ||
        !sl_array_reserve(a, &s->transforms, sizeof(sl_affine), 1) || !sl_scene_names_reserve(s))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_add_object: out of memory");
    /* material ids: once one object has a material, object_materials covers every object */
    if (material || s->object_materials.count) {
        size_t pad = s->objects.count - SL_MIN(s->objects.count, s->object_materials.count);
        if (!sl_array_reserve(a, &s->object_materials, sizeof(uint32_t), pad + 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_add_object: out of memory");
        sl_array_push(a, &s->object_materials, sizeof(uint32_t), NULL, pad);
        sl_array_push(a, &s->object_materials, sizeof(uint32_t), &material, 1);
    }
    /* dynamic objects always get a transform slot so that they can move later */
    if ((d->transform && !affine_is_identity(d->transform)) || (d->flags & SL_OBJECT_DYNAMIC)) {
        sl_affine t = d->transform ? *d->transform : sl_affine_identity();
        rec.transform = (uint32_t)s->transforms.count;
        sl_array_push(a, &s->transforms, sizeof t, &t, 1);
    }
    sl_array_push(a, &s->objects, sizeof rec, &rec, 1);
    sl_array_push(a, &s->bounds, sizeof(sl_aabb), NULL, 1);
    sl_scene_names_on_add(s);
    uint32_t id = (uint32_t)(s->objects.count - 1);
    sl_scene_update_object_bounds(s, id);
    if (out_object)
        *out_object = id;
    return SL_OK;
}

sl_status sl_scene_set_object_transform(sl_scene s, uint32_t object, const sl_affine *t, sl_error *err)
{
    if (!s || !t || object >= s->objects.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_object_transform: bad object %u", object);
    if (!affine_finite(t))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "object %u: transform is not finite", object);
    const sl_allocator *a = A(s);
    if (!sl_array_own(a, &s->objects, sizeof(sl_object_rec)) || !sl_array_own(a, &s->transforms, sizeof(sl_affine)) ||
        !sl_array_own(a, &s->bounds, sizeof(sl_aabb)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_transform: out of memory");
    sl_object_rec *o = &SL_AT(s->objects, sl_object_rec, object);
    if (o->transform == SL_NONE) {
        if (!sl_array_reserve(a, &s->transforms, sizeof(sl_affine), 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_transform: out of memory");
        o->transform = (uint32_t)s->transforms.count;
        sl_array_push(a, &s->transforms, sizeof(sl_affine), t, 1);
    } else {
        SL_AT(s->transforms, sl_affine, o->transform) = *t;
    }
    sl_scene_update_object_bounds(s, object);
    return SL_OK;
}

/* Signed area of a polygon (positive when CCW). */
static double polygon_area(const float *xy, uint32_t n)
{
    double a = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        a += (double)xy[2 * i] * xy[2 * j + 1] - (double)xy[2 * j] * xy[2 * i + 1];
    }
    return 0.5 * a;
}

static int orient(const float *a, const float *b, const float *c)
{
    double v = ((double)b[0] - a[0]) * ((double)c[1] - a[1]) - ((double)b[1] - a[1]) * ((double)c[0] - a[0]);
    return (v > 0) - (v < 0);
}

static bool on_segment(const float *a, const float *b, const float *p)
{
    return fminf(a[0], b[0]) <= p[0] && p[0] <= fmaxf(a[0], b[0]) && fminf(a[1], b[1]) <= p[1] && p[1] <= fmaxf(a[1], b[1]);
}

static bool segments_intersect(const float *a, const float *b, const float *c, const float *d)
{
    int o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
    if (o1 != o2 && o3 != o4)
        return true;
    return (o1 == 0 && on_segment(a, b, c)) || (o2 == 0 && on_segment(a, b, d)) || (o3 == 0 && on_segment(c, d, a)) ||
           (o4 == 0 && on_segment(c, d, b));
}

/* Simple-polygon check: no two non-adjacent edges touch. Quadratic, fine for footprints (tens of
 * vertices); longer polygons use the same test but are rare. */
static bool polygon_is_simple(const float *xy, uint32_t n, uint32_t *bad_i, uint32_t *bad_j)
{
    for (uint32_t i = 0; i < n; i++) {
        uint32_t i2 = (i + 1) % n;
        for (uint32_t j = i + 2; j < n; j++) {
            uint32_t j2 = (j + 1) % n;
            if (j2 == i)
                continue;
            if (segments_intersect(xy + 2 * i, xy + 2 * i2, xy + 2 * j, xy + 2 * j2)) {
                *bad_i = i, *bad_j = j;
                return false;
            }
        }
    }
    return true;
}

bool sl_scene_polygon_ok(const float *xy, uint32_t n)
{
    if (!xy)
        return false;
    if (n >= 2 && xy[0] == xy[2 * (n - 1)] && xy[1] == xy[2 * (n - 1) + 1])
        n--;
    if (n < 3)
        return false;
    for (uint32_t i = 0; i < n; i++)
        if (!isfinite(xy[2 * i]) || !isfinite(xy[2 * i + 1]))
            return false;
    uint32_t bi, bj;
    return fabs(polygon_area(xy, n)) > 1e-9 && polygon_is_simple(xy, n, &bi, &bj);
}

/* Validate a polygon and append it CCW to an xy array. */
sl_status sl_scene_push_polygon(struct sl_scene_t *s, sl_array *xy_arr, const float *xy, uint32_t n, const char *what,
                                uint32_t *first, uint32_t *count, sl_error *err)
{
    if (!xy)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: NULL vertices", what);
    if (n >= 2 && xy[0] == xy[2 * (n - 1)] && xy[1] == xy[2 * (n - 1) + 1])
        n--; /* drop a repeated closing vertex */
    if (n < 3)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: %u vertices, need at least 3", what, n);
    for (uint32_t i = 0; i < n; i++)
        if (!isfinite(xy[2 * i]) || !isfinite(xy[2 * i + 1]))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: vertex %u is not finite", what, i);
    double area = polygon_area(xy, n);
    if (!(fabs(area) > 1e-9))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: zero area", what);
    uint32_t bi, bj;
    if (!polygon_is_simple(xy, n, &bi, &bj))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: not simple (edges %u and %u intersect)", what, bi, bj);
    const sl_allocator *a = A(s);
    if (xy_arr->count / 2 + n > UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "%s: too many polygon vertices", what);
    float *dst = sl_array_push(a, xy_arr, sizeof(float), NULL, 2 * (size_t)n);
    if (!dst)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", what);
    *first = (uint32_t)(xy_arr->count / 2 - n);
    *count = n;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t k = area > 0 ? i : n - 1 - i;
        dst[2 * i] = xy[2 * k];
        dst[2 * i + 1] = xy[2 * k + 1];
    }
    return SL_OK;
}

sl_status sl_scene_add_footprint(sl_scene s, const sl_footprint_desc *d, uint32_t *out_index, sl_error *err)
{
    if (!s || !d)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_footprint: NULL argument");
    char what[64];
    snprintf(what, sizeof what, "footprint %zu", s->footprints.count);
    if (!isfinite(d->base_z) || !isfinite(d->roof_z) || !(d->roof_z > d->base_z))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: roof height %g must exceed base height %g", what, d->roof_z,
                       d->base_z);
    if (d->object != SL_NONE && d->object >= s->objects.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: object %u does not exist", what, d->object);
    if (d->object != SL_NONE && (sl_scene_objects(s)[d->object].flags & SL_OBJECT_SEE_THROUGH))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: object %u is see-through: it never occludes", what, d->object);
    if (!sl_array_reserve(A(s), &s->footprints, sizeof(sl_footprint_rec), 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", what);
    sl_footprint_rec rec = {0, 0, d->base_z, d->roof_z, d->object, 0};
    sl_status st = sl_scene_push_polygon(s, &s->footprint_xy, d->xy, d->vertex_count, what, &rec.first_vertex, &rec.vertex_count, err);
    if (st != SL_OK)
        return st;
    sl_array_push(A(s), &s->footprints, sizeof rec, &rec, 1);
    if (out_index)
        *out_index = (uint32_t)(s->footprints.count - 1);
    return SL_OK;
}

sl_status sl_scene_add_occluder(sl_scene s, uint32_t mesh, const sl_affine *t, uint32_t object, sl_error *err)
{
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_occluder: NULL scene");
    if (mesh >= s->meshes.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_occluder: mesh %u does not exist", mesh);
    if (object != SL_NONE && object >= s->objects.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_occluder: object %u does not exist", object);
    if (object != SL_NONE && (sl_scene_objects(s)[object].flags & SL_OBJECT_SEE_THROUGH))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_occluder: object %u is see-through: it never occludes",
                       object);
    if (t && !affine_finite(t))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_occluder: transform is not finite");
    const sl_allocator *a = A(s);
    if (!sl_array_reserve(a, &s->occluders, sizeof(sl_occluder_rec), 1) || !sl_array_reserve(a, &s->transforms, sizeof(sl_affine), 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_add_occluder: out of memory");
    sl_occluder_rec rec = {mesh, SL_NONE, object, 0};
    if (t && !affine_is_identity(t)) {
        rec.transform = (uint32_t)s->transforms.count;
        sl_array_push(a, &s->transforms, sizeof *t, t, 1);
    }
    sl_array_push(a, &s->occluders, sizeof rec, &rec, 1);
    return SL_OK;
}

/* ---- materials ---- */

const char *sl_texture_path_problem(const char *p, size_t len)
{
    if (len == 0)
        return "is empty";
    if (len > SL_TEXTURE_PATH_MAX)
        return "is longer than 1024 bytes";
    if (p[0] == '/')
        return "is absolute";
    size_t start = 0;
    for (size_t i = 0; i <= len; i++) {
        if (i < len) {
            unsigned char c = (unsigned char)p[i];
            if (c < 0x20 || c == 0x7f)
                return "contains a control character or NUL";
            if (c == '\\')
                return "contains a backslash";
            if (c != '/')
                continue;
        }
        size_t n = i - start;
        if (n == 0)
            return "has an empty component";
        if (n == 1 && p[start] == '.')
            return "has a '.' component";
        if (n == 2 && p[start] == '.' && p[start + 1] == '.')
            return "contains a '..' component";
        start = i + 1;
    }
    return NULL;
}

bool sl_texture_path_check(const char *path, const char **why)
{
    const char *w = path ? sl_texture_path_problem(path, strnlen(path, SL_TEXTURE_PATH_MAX + 1)) : "is NULL";
    if (why)
        *why = w;
    return w == NULL;
}

const char *sl_material_rec_problem(const sl_material_rec *m)
{
    for (int k = 0; k < 4; k++)
        if (!(m->base_color[k] >= 0.0f && m->base_color[k] <= 1.0f)) /* NaN fails too */
            return "base colour outside [0, 1] or not finite";
    if (m->alpha_mode > SL_ALPHA_BLEND)
        return "unknown alpha mode";
    if (!(m->alpha_cutoff >= 0.0f && m->alpha_cutoff <= 1.0f))
        return "alpha cutoff outside [0, 1] or not finite";
    if (m->flags & ~(uint32_t)SL_MATERIAL_DOUBLE_SIDED)
        return "unknown flag bits";
    return NULL;
}

sl_status sl_scene_add_material(sl_scene s, const sl_material *d, uint32_t *out_material, sl_error *err)
{
    if (!s || !d)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_material: NULL argument");
    size_t id = s->materials.count + 1;
    if (id >= SL_NONE)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_scene_add_material: too many materials");
    sl_material_rec rec;
    memset(&rec, 0, sizeof rec);
    memcpy(rec.base_color, d->base_color, sizeof rec.base_color);
    rec.alpha_mode = d->alpha_mode;
    rec.alpha_cutoff = d->alpha_cutoff;
    rec.flags = d->flags;
    const char *why = sl_material_rec_problem(&rec);
    if (why)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "material %zu: %s", id, why);
    const char *tex = d->base_color_texture && d->base_color_texture[0] ? d->base_color_texture : NULL;
    size_t len = tex ? strnlen(tex, SL_TEXTURE_PATH_MAX + 1) : 0;
    if (tex && (why = sl_texture_path_problem(tex, len)) != NULL)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "material %zu: texture path \"%.64s\" %s", id, tex, why);
    if (s->material_text.count + len + 1 > UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "material %zu: too many texture path bytes", id);
    const sl_allocator *a = A(s);
    if (!sl_array_reserve(a, &s->materials, sizeof rec, 1) || (tex && !sl_array_reserve(a, &s->material_text, 1, len + 1)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_add_material: out of memory");
    if (tex) {
        rec.texture_offset = (uint32_t)s->material_text.count;
        rec.texture_length = (uint32_t)len;
        sl_array_push(a, &s->material_text, 1, tex, len);
        sl_array_push(a, &s->material_text, 1, NULL, 1);
    }
    sl_array_push(a, &s->materials, sizeof rec, &rec, 1);
    if (out_material)
        *out_material = (uint32_t)id;
    return SL_OK;
}

sl_status sl_scene_set_base_dir(sl_scene s, const char *dir, sl_error *err)
{
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_base_dir: NULL scene");
    char *copy = NULL;
    if (dir && dir[0] && !(copy = sl_strdup(A(s), dir)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_base_dir: out of memory");
    sl_strfree(A(s), s->base_dir);
    s->base_dir = copy;
    return SL_OK;
}

sl_status sl_scene_set_base_dir_of(sl_scene scene, const char *path, sl_error *err)
{
    const char *slash = strrchr(path, '/');
    if (!slash)
        return sl_scene_set_base_dir(scene, ".", err);
    if (slash == path)
        return sl_scene_set_base_dir(scene, "/", err);
    size_t n = (size_t)(slash - path);
    char *dir = sl_alloc(&scene->alloc, n + 1);
    if (!dir)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    memcpy(dir, path, n);
    dir[n] = 0;
    sl_status st = sl_scene_set_base_dir(scene, dir, err);
    sl_free(&scene->alloc, dir, n + 1);
    return st;
}

uint32_t sl_scene_material_count(sl_scene s) { return (uint32_t)s->materials.count; }

bool sl_scene_material(sl_scene s, uint32_t id, sl_material *out)
{
    if (out)
        memset(out, 0, sizeof *out);
    if (id == SL_MATERIAL_NONE || id > s->materials.count)
        return false;
    const sl_material_rec *m = &SL_AT(s->materials, sl_material_rec, id - 1);
    if (out) {
        memcpy(out->base_color, m->base_color, sizeof out->base_color);
        out->base_color_texture = m->texture_length ? (const char *)s->material_text.data + m->texture_offset : NULL;
        out->alpha_mode = m->alpha_mode;
        out->alpha_cutoff = m->alpha_cutoff;
        out->flags = m->flags;
    }
    return true;
}

uint32_t sl_scene_object_material(sl_scene s, uint32_t object)
{
    if (object >= s->object_materials.count)
        return SL_MATERIAL_NONE;
    uint32_t m = SL_AT(s->object_materials, uint32_t, object);
    return m <= s->materials.count ? m : SL_MATERIAL_NONE;
}

const char *sl_scene_base_dir(sl_scene s) { return s->base_dir; }

sl_status sl_scene_texture_path(sl_scene s, uint32_t material, char *buf, size_t cap, sl_error *err)
{
    sl_material m;
    if (!s || !buf)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_texture_path: NULL argument");
    if (cap)
        buf[0] = 0;
    if (!sl_scene_material(s, material, &m))
        return sl_fail(err, SL_ERROR_NOT_FOUND, "material %u does not exist (%u materials)", material,
                       sl_scene_material_count(s));
    if (!m.base_color_texture)
        return sl_fail(err, SL_ERROR_NOT_FOUND, "material %u has no base-colour texture", material);
    if (!s->base_dir)
        return sl_fail(err, SL_ERROR_NOT_FOUND, "material %u: texture \"%s\": the scene has no base folder", material,
                       m.base_color_texture);
    char *root = realpath(s->base_dir, NULL);
    if (!root)
        return sl_fail(err, SL_ERROR_NOT_FOUND, "material %u: base folder %s: %s", material, s->base_dir, strerror(errno));
    size_t rl = strlen(root), need = strlen(s->base_dir) + 1 + strlen(m.base_color_texture) + 1;
    char *joined = malloc(need);
    sl_status st = SL_OK;
    char *file = NULL;
    if (!joined) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_texture_path: out of memory");
        goto done;
    }
    snprintf(joined, need, "%s/%s", s->base_dir, m.base_color_texture);
    file = realpath(joined, NULL);
    if (!file) {
        st = sl_fail(err, SL_ERROR_NOT_FOUND, "material %u: texture %s: %s", material, joined, strerror(errno));
        goto done;
    }
    /* inside the base folder: the resolved root is a prefix followed by '/' (root "/" included) */
    bool inside = strncmp(file, root, rl) == 0 && (file[rl] == '/' || (rl == 1 && root[0] == '/'));
    struct stat sb;
    if (!inside) {
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "material %u: texture %s resolves to %s, outside the base folder %s",
                     material, joined, file, root);
    } else if (stat(file, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "material %u: texture %s is not a regular file", material, file);
    } else if (strlen(file) + 1 > cap) {
        st = sl_fail(err, SL_ERROR_LIMIT, "material %u: texture path %s needs %zu bytes, buffer has %zu", material, file,
                     strlen(file) + 1, cap);
    } else {
        memcpy(buf, file, strlen(file) + 1);
    }
done:
    free(file);
    free(joined);
    free(root);
    return st;
}

sl_status sl_scene_set_terrain(sl_scene s, const sl_terrain_desc *d, sl_error *err)
{
    if (!s || !d || !d->heights)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_terrain: NULL argument");
    if (d->nx < 2 || d->ny < 2 || !(d->cell > 0) || !isfinite(d->cell) || !isfinite(d->origin_x) || !isfinite(d->origin_y))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "terrain: need nx, ny >= 2 and a positive cell (got %u x %u, %g)",
                       d->nx, d->ny, d->cell);
    size_t n;
    if (!sl_mul_size(d->nx, d->ny, &n) || n > (1u << 30))
        return sl_fail(err, SL_ERROR_LIMIT, "terrain: %u x %u samples is too many", d->nx, d->ny);
    for (size_t i = 0; i < n; i++)
        if (!isfinite(d->heights[i]))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "terrain: sample %zu is not finite", i);
    sl_array_free(A(s), &s->terrain_heights, sizeof(float));
    if (!sl_array_push(A(s), &s->terrain_heights, sizeof(float), d->heights, n))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "terrain: out of memory");
    s->has_terrain = true;
    s->terrain_nx = d->nx, s->terrain_ny = d->ny;
    s->terrain_origin_x = d->origin_x, s->terrain_origin_y = d->origin_y, s->terrain_cell = d->cell;
    return SL_OK;
}

sl_status sl_scene_add_street_polygon(sl_scene s, const float *xy, uint32_t n, sl_error *err)
{
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_street_polygon: NULL scene");
    char what[64];
    snprintf(what, sizeof what, "street polygon %zu", s->street_polys.count);
    if (!sl_array_reserve(A(s), &s->street_polys, sizeof(sl_polygon_rec), 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", what);
    sl_polygon_rec rec;
    sl_status st = sl_scene_push_polygon(s, &s->street_xy, xy, n, what, &rec.first_vertex, &rec.vertex_count, err);
    if (st != SL_OK)
        return st;
    sl_array_push(A(s), &s->street_polys, sizeof rec, &rec, 1);
    return SL_OK;
}

sl_status sl_scene_set_street_graph(sl_scene s, const sl_street_node *nodes, uint32_t node_count, const sl_street_edge *edges,
                                    uint32_t edge_count, sl_error *err)
{
    if (!s || (node_count && !nodes) || (edge_count && !edges))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_street_graph: NULL argument");
    for (uint32_t i = 0; i < node_count; i++)
        if (!isfinite(nodes[i].x) || !isfinite(nodes[i].y))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "street node %u is not finite", i);
    for (uint32_t i = 0; i < edge_count; i++)
        if (edges[i].a >= node_count || edges[i].b >= node_count)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "street edge %u: node out of range (node %u, %u nodes)", i,
                           edges[i].a >= node_count ? edges[i].a : edges[i].b, node_count);
        else if (!isfinite(edges[i].width) || !(edges[i].width >= 0))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "street edge %u: width %g is %s", i, (double)edges[i].width,
                           isnan(edges[i].width) ? "NaN" : edges[i].width < 0 ? "negative" : "infinite");
    const sl_allocator *a = A(s);
    sl_array_free(a, &s->street_nodes, sizeof(sl_street_node));
    sl_array_free(a, &s->street_edges, sizeof(sl_street_edge));
    if ((node_count && !sl_array_push(a, &s->street_nodes, sizeof *nodes, nodes, node_count)) ||
        (edge_count && !sl_array_push(a, &s->street_edges, sizeof *edges, edges, edge_count)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street graph: out of memory");
    return SL_OK;
}

/* A node's or leaf's box: every coordinate finite ("mins.x is NaN", "maxs.z is infinite"). The
 * lookups and the portal and region methods compare points against these boxes, where a NaN
 * compares false both ways and an infinity swallows the whole map. */
static sl_status check_bsp_box(const sl_aabb *b, const char *what, uint32_t i, sl_status code, sl_error *err)
{
    const float v[6] = {b->min.x, b->min.y, b->min.z, b->max.x, b->max.y, b->max.z};
    for (int k = 0; k < 6; k++)
        if (!isfinite(v[k]))
            return sl_fail(err, code, "bsp %s %u: %s.%c is %s", what, i, k < 3 ? "mins" : "maxs", "xyz"[k % 3],
                           isnan(v[k]) ? "NaN" : "infinite");
    return SL_OK;
}

/* Shared BSP validation for sl_scene_set_bsp and the loaders. */
static sl_status validate_bsp(const sl_bsp_desc *d, uint32_t object_count, sl_status code, sl_error *err)
{
    for (uint32_t i = 0; i < d->plane_count; i++) {
        const sl_plane *p = &d->planes[i];
        if (!isfinite(p->a) || !isfinite(p->b) || !isfinite(p->c) || !isfinite(p->d))
            return sl_fail(err, code, "bsp plane %u is not finite", i);
    }
    for (uint32_t i = 0; i < d->node_count; i++) {
        const sl_bsp_node *n = &d->nodes[i];
        if (n->plane >= d->plane_count)
            return sl_fail(err, code, "bsp node %u: plane %u out of range (%u planes)", i, n->plane, d->plane_count);
        for (int c = 0; c < 2; c++) {
            int32_t ch = n->children[c];
            /* children must point forward so that traversal terminates */
            if (ch >= 0 ? ((uint32_t)ch <= i || (uint32_t)ch >= d->node_count)
                        : ((uint32_t)(-(int64_t)ch - 1) >= d->leaf_count))
                return sl_fail(err, code, "bsp node %u: child %d out of range", i, ch);
        }
        sl_status st = check_bsp_box(&n->bounds, "node", i, code, err);
        if (st != SL_OK)
            return st;
    }
    for (uint32_t i = 0; i < d->leaf_count; i++) {
        const sl_bsp_leaf *l = &d->leaves[i];
        if (l->cluster < -1 || (l->cluster >= 0 && (uint32_t)l->cluster >= d->cluster_count))
            return sl_fail(err, code, "bsp leaf %u: cluster %d out of range (%u clusters)", i, l->cluster,
                           d->cluster_count);
        if ((uint64_t)l->first_object + l->object_count > d->leaf_object_count)
            return sl_fail(err, code, "bsp leaf %u: object range out of bounds", i);
        sl_status st = check_bsp_box(&l->bounds, "leaf", i, code, err);
        if (st != SL_OK)
            return st;
    }
    for (uint32_t i = 0; i < d->leaf_object_count; i++)
        if (d->leaf_objects[i] >= object_count)
            return sl_fail(err, code, "bsp leaf-object %u: object %u does not exist", i, d->leaf_objects[i]);
    if (d->pvs && (uint64_t)d->cluster_bytes * 8 < d->cluster_count)
        return sl_fail(err, code, "bsp vis: %u bytes per cluster cannot hold %u clusters", d->cluster_bytes,
                       d->cluster_count);
    return SL_OK;
}

sl_status sl_scene_set_bsp(sl_scene s, const sl_bsp_desc *d, sl_error *err)
{
    if (!s || !d || (d->plane_count && !d->planes) || (d->node_count && !d->nodes) || (d->leaf_count && !d->leaves) ||
        (d->leaf_object_count && !d->leaf_objects))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_bsp: NULL argument");
    sl_status st = validate_bsp(d, (uint32_t)s->objects.count, SL_ERROR_INVALID_ARGUMENT, err);
    if (st != SL_OK)
        return st;
    const sl_allocator *a = A(s);
    sl_array_free(a, &s->bsp_planes, sizeof(sl_plane));
    sl_array_free(a, &s->bsp_nodes, sizeof(sl_bsp_node));
    sl_array_free(a, &s->bsp_leaves, sizeof(sl_bsp_leaf));
    sl_array_free(a, &s->bsp_leaf_objects, sizeof(uint32_t));
    sl_array_free(a, &s->bsp_pvs, 1);
    size_t pvs_bytes = d->pvs ? (size_t)d->cluster_count * d->cluster_bytes : 0;
    if ((d->plane_count && !sl_array_push(a, &s->bsp_planes, sizeof(sl_plane), d->planes, d->plane_count)) ||
        (d->node_count && !sl_array_push(a, &s->bsp_nodes, sizeof(sl_bsp_node), d->nodes, d->node_count)) ||
        (d->leaf_count && !sl_array_push(a, &s->bsp_leaves, sizeof(sl_bsp_leaf), d->leaves, d->leaf_count)) ||
        (d->leaf_object_count && !sl_array_push(a, &s->bsp_leaf_objects, sizeof(uint32_t), d->leaf_objects, d->leaf_object_count)) ||
        (pvs_bytes && !sl_array_push(a, &s->bsp_pvs, 1, d->pvs, pvs_bytes)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bsp: out of memory");
    s->has_bsp = true;
    s->bsp_cluster_count = d->cluster_count;
    s->bsp_cluster_bytes = d->pvs ? d->cluster_bytes : 0;
    return SL_OK;
}

sl_status sl_scene_set_meta(sl_scene s, const char *key, const char *value, sl_error *err)
{
    if (!s || !key || !value || !key[0])
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_meta: empty key or NULL value");
    const sl_allocator *a = A(s);
    char *v = sl_strdup(a, value);
    if (!v)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_meta: out of memory");
    for (size_t i = 0; i < s->meta.count; i++) {
        sl_meta_rec *m = &SL_AT(s->meta, sl_meta_rec, i);
        if (strcmp(m->key, key) == 0) {
            sl_strfree(a, m->value);
            m->value = v;
            return SL_OK;
        }
    }
    sl_meta_rec rec = {sl_strdup(a, key), v};
    if (!rec.key || !sl_array_push(a, &s->meta, sizeof rec, &rec, 1)) {
        sl_strfree(a, rec.key);
        sl_strfree(a, v);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_meta: out of memory");
    }
    return SL_OK;
}

/* ---- reading ---- */

uint32_t sl_scene_mesh_count(sl_scene s) { return (uint32_t)s->meshes.count; }
uint32_t sl_scene_object_count(sl_scene s) { return (uint32_t)s->objects.count; }
uint32_t sl_scene_footprint_count(sl_scene s) { return (uint32_t)s->footprints.count; }
uint32_t sl_scene_occluder_count(sl_scene s) { return (uint32_t)s->occluders.count; }
uint32_t sl_scene_street_polygon_count(sl_scene s) { return (uint32_t)s->street_polys.count; }

sl_mesh_view sl_scene_mesh(sl_scene s, uint32_t mesh)
{
    sl_mesh_view v;
    memset(&v, 0, sizeof v);
    if (mesh >= s->meshes.count)
        return v;
    const sl_mesh_rec *m = &sl_scene_meshes(s)[mesh];
    v.positions = sl_scene_positions(s) + 3 * m->first_vertex;
    v.normals = (const float *)s->normals.data + 3 * m->first_vertex;
    v.vertex_count = m->vertex_count;
    v.indices = sl_scene_indices(s) + m->first_index;
    v.triangle_count = m->triangle_count;
    v.bounds = m->bounds;
    if (mesh < s->mesh_uvs.count && ((const uint8_t *)s->mesh_uvs.data)[mesh] &&
        2 * (m->first_vertex + m->vertex_count) <= s->uvs.count)
        v.uvs = (const float *)s->uvs.data + 2 * m->first_vertex;
    return v;
}

sl_object_view sl_scene_object(sl_scene s, uint32_t object)
{
    sl_object_view v;
    memset(&v, 0, sizeof v);
    if (object >= s->objects.count)
        return v;
    const sl_object_rec *o = &sl_scene_objects(s)[object];
    v.mesh = o->mesh;
    v.color = o->color;
    v.kind = o->kind;
    v.flags = o->flags;
    v.identity = o->transform == SL_NONE;
    v.transform = v.identity ? sl_affine_identity() : sl_scene_transforms(s)[o->transform];
    v.bounds = SL_AT(s->bounds, sl_aabb, object);
    v.triangle_count = sl_scene_meshes(s)[o->mesh].triangle_count;
    v.material = sl_scene_object_material(s, object);
    return v;
}

sl_aabb sl_scene_object_bounds(sl_scene s, uint32_t object)
{
    return object < s->objects.count ? SL_AT(s->bounds, sl_aabb, object) : sl_aabb_empty();
}

const sl_aabb *sl_scene_object_bounds_array(sl_scene s) { return (const sl_aabb *)s->bounds.data; }

sl_footprint_view sl_scene_footprint(sl_scene s, uint32_t index)
{
    sl_footprint_view v;
    memset(&v, 0, sizeof v);
    if (index >= s->footprints.count)
        return v;
    const sl_footprint_rec *f = &SL_AT(s->footprints, sl_footprint_rec, index);
    v.xy = (const float *)s->footprint_xy.data + 2 * (size_t)f->first_vertex;
    v.vertex_count = f->vertex_count;
    v.base_z = f->base_z;
    v.roof_z = f->roof_z;
    v.object = f->object;
    return v;
}

bool sl_scene_footprint_moves(sl_scene s, uint32_t index)
{
    if (!s || index >= s->footprints.count)
        return false;
    uint32_t o = SL_AT(s->footprints, sl_footprint_rec, index).object;
    return o < s->objects.count && (SL_AT(s->objects, sl_object_rec, o).flags & SL_OBJECT_DYNAMIC) != 0;
}

void sl_footprint_facade(const sl_footprint_view *fp, uint32_t edge, sl_vec3 quad[4])
{
    uint32_t i = edge % fp->vertex_count, j = (i + 1) % fp->vertex_count;
    float ax = fp->xy[2 * i], ay = fp->xy[2 * i + 1], bx = fp->xy[2 * j], by = fp->xy[2 * j + 1];
    quad[0] = (sl_vec3){ax, ay, fp->base_z};
    quad[1] = (sl_vec3){bx, by, fp->base_z};
    quad[2] = (sl_vec3){bx, by, fp->roof_z};
    quad[3] = (sl_vec3){ax, ay, fp->roof_z};
}

sl_occluder_view sl_scene_occluder(sl_scene s, uint32_t index)
{
    sl_occluder_view v;
    memset(&v, 0, sizeof v);
    if (index >= s->occluders.count)
        return v;
    const sl_occluder_rec *o = &SL_AT(s->occluders, sl_occluder_rec, index);
    v.mesh = o->mesh;
    v.object = o->object;
    v.transform = o->transform == SL_NONE ? sl_affine_identity() : sl_scene_transforms(s)[o->transform];
    return v;
}

bool sl_scene_terrain(sl_scene s, sl_terrain_view *out)
{
    if (!s->has_terrain)
        return false;
    if (out) {
        out->nx = s->terrain_nx;
        out->ny = s->terrain_ny;
        out->origin_x = s->terrain_origin_x;
        out->origin_y = s->terrain_origin_y;
        out->cell = s->terrain_cell;
        out->heights = (const float *)s->terrain_heights.data;
    }
    return true;
}

float sl_scene_ground_height(sl_scene s, float x, float y)
{
    if (!s->has_terrain)
        return 0.0f;
    const float *h = (const float *)s->terrain_heights.data;
    float fx = (x - s->terrain_origin_x) / s->terrain_cell, fy = (y - s->terrain_origin_y) / s->terrain_cell;
    fx = SL_CLAMP(fx, 0.0f, (float)(s->terrain_nx - 1));
    fy = SL_CLAMP(fy, 0.0f, (float)(s->terrain_ny - 1));
    uint32_t i = (uint32_t)fx, j = (uint32_t)fy;
    if (i >= s->terrain_nx - 1)
        i = s->terrain_nx - 2;
    if (j >= s->terrain_ny - 1)
        j = s->terrain_ny - 2;
    float u = fx - (float)i, v = fy - (float)j;
    size_t nx = s->terrain_nx;
    float h00 = h[j * nx + i], h10 = h[j * nx + i + 1], h01 = h[(j + 1) * nx + i], h11 = h[(j + 1) * nx + i + 1];
    return (h00 * (1 - u) + h10 * u) * (1 - v) + (h01 * (1 - u) + h11 * u) * v;
}

sl_polygon_view sl_scene_street_polygon(sl_scene s, uint32_t index)
{
    sl_polygon_view v = {NULL, 0};
    if (index >= s->street_polys.count)
        return v;
    const sl_polygon_rec *p = &SL_AT(s->street_polys, sl_polygon_rec, index);
    v.xy = (const float *)s->street_xy.data + 2 * (size_t)p->first_vertex;
    v.vertex_count = p->vertex_count;
    return v;
}

void sl_scene_street_graph(sl_scene s, const sl_street_node **nodes, uint32_t *node_count, const sl_street_edge **edges,
                           uint32_t *edge_count)
{
    if (nodes)
        *nodes = (const sl_street_node *)s->street_nodes.data;
    if (node_count)
        *node_count = (uint32_t)s->street_nodes.count;
    if (edges)
        *edges = (const sl_street_edge *)s->street_edges.data;
    if (edge_count)
        *edge_count = (uint32_t)s->street_edges.count;
}

bool sl_scene_bsp(sl_scene s, sl_bsp_view *out)
{
    if (!s->has_bsp)
        return false;
    if (out) {
        out->planes = (const sl_plane *)s->bsp_planes.data;
        out->plane_count = (uint32_t)s->bsp_planes.count;
        out->nodes = (const sl_bsp_node *)s->bsp_nodes.data;
        out->node_count = (uint32_t)s->bsp_nodes.count;
        out->leaves = (const sl_bsp_leaf *)s->bsp_leaves.data;
        out->leaf_count = (uint32_t)s->bsp_leaves.count;
        out->leaf_objects = (const uint32_t *)s->bsp_leaf_objects.data;
        out->leaf_object_count = (uint32_t)s->bsp_leaf_objects.count;
        out->cluster_count = s->bsp_cluster_count;
        out->cluster_bytes = s->bsp_cluster_bytes;
        out->pvs = s->bsp_pvs.count ? (const uint8_t *)s->bsp_pvs.data : NULL;
    }
    return true;
}

int32_t sl_scene_bsp_find_leaf(sl_scene s, sl_vec3 p)
{
    if (!s->has_bsp)
        return -1;
    if (s->bsp_nodes.count == 0)
        return s->bsp_leaves.count ? 0 : -1;
    const sl_bsp_node *nodes = (const sl_bsp_node *)s->bsp_nodes.data;
    const sl_plane *planes = (const sl_plane *)s->bsp_planes.data;
    int32_t n = 0;
    /* validated: children point strictly forward, so this terminates */
    while (n >= 0) {
        const sl_plane *pl = &planes[nodes[n].plane];
        float d = pl->a * p.x + pl->b * p.y + pl->c * p.z + pl->d;
        n = nodes[n].children[d >= 0 ? 0 : 1];
    }
    return -(n + 1);
}

const char *sl_scene_meta(sl_scene s, const char *key)
{
    for (size_t i = 0; i < s->meta.count; i++) {
        const sl_meta_rec *m = &SL_AT(s->meta, sl_meta_rec, i);
        if (strcmp(m->key, key) == 0)
            return m->value;
    }
    return NULL;
}

uint32_t sl_scene_meta_count(sl_scene s) { return (uint32_t)s->meta.count; }

void sl_scene_meta_at(sl_scene s, uint32_t i, const char **key, const char **value)
{
    const sl_meta_rec *m = i < s->meta.count ? &SL_AT(s->meta, sl_meta_rec, i) : NULL;
    if (key)
        *key = m ? m->key : NULL;
    if (value)
        *value = m ? m->value : NULL;
}

sl_aabb sl_scene_bounds(sl_scene s)
{
    sl_aabb b = sl_aabb_empty();
    const sl_aabb *ob = (const sl_aabb *)s->bounds.data;
    for (size_t i = 0; i < s->objects.count; i++)
        sl_aabb_merge(&b, &ob[i]);
    return b;
}

static size_t arr_bytes(const sl_array *a, size_t elem) { return (a->cap ? a->cap : 0) * elem; }

void sl_scene_get_stats(sl_scene s, sl_scene_stats *st)
{
    memset(st, 0, sizeof *st);
    st->mesh_count = (uint32_t)s->meshes.count;
    st->object_count = (uint32_t)s->objects.count;
    st->footprint_count = (uint32_t)s->footprints.count;
    st->occluder_count = (uint32_t)s->occluders.count;
    st->vertex_count = s->positions.count / 3;
    st->triangle_count = s->indices.count / 3;
    st->street_polygon_count = (uint32_t)s->street_polys.count;
    st->street_node_count = (uint32_t)s->street_nodes.count;
    st->street_edge_count = (uint32_t)s->street_edges.count;
    st->has_terrain = s->has_terrain;
    st->has_bsp = s->has_bsp;
    st->bsp_leaf_count = (uint32_t)s->bsp_leaves.count;
    st->bsp_cluster_count = s->bsp_cluster_count;
    const sl_object_rec *o = sl_scene_objects(s);
    const sl_mesh_rec *m = sl_scene_meshes(s);
    for (size_t i = 0; i < s->objects.count; i++) {
        uint64_t t = m[o[i].mesh].triangle_count;
        st->instanced_triangle_count += t;
        uint32_t k = o[i].kind < SL_KIND_COUNT ? o[i].kind : SL_KIND_OTHER;
        st->objects_per_kind[k]++;
        st->triangles_per_kind[k] += t;
        st->see_through_count += (o[i].flags & SL_OBJECT_SEE_THROUGH) != 0;
    }
    st->material_count = (uint32_t)s->materials.count;
    for (size_t i = 0; i < s->mesh_uvs.count; i++)
        st->uv_mesh_count += ((const uint8_t *)s->mesh_uvs.data)[i] != 0;
    st->memory_bytes = sizeof *s + s->mapping.size + arr_bytes(&s->meshes, sizeof(sl_mesh_rec)) +
                       arr_bytes(&s->positions, 4) + arr_bytes(&s->normals, 4) + arr_bytes(&s->indices, 4) +
                       arr_bytes(&s->objects, sizeof(sl_object_rec)) + arr_bytes(&s->bounds, sizeof(sl_aabb)) +
                       arr_bytes(&s->transforms, sizeof(sl_affine)) + arr_bytes(&s->footprints, sizeof(sl_footprint_rec)) +
                       arr_bytes(&s->footprint_xy, 4) + arr_bytes(&s->occluders, sizeof(sl_occluder_rec)) +
                       arr_bytes(&s->terrain_heights, 4) + arr_bytes(&s->street_polys, sizeof(sl_polygon_rec)) +
                       arr_bytes(&s->street_xy, 4) + arr_bytes(&s->street_nodes, sizeof(sl_street_node)) +
                       arr_bytes(&s->street_edges, sizeof(sl_street_edge)) + arr_bytes(&s->bsp_planes, sizeof(sl_plane)) +
                       arr_bytes(&s->bsp_nodes, sizeof(sl_bsp_node)) + arr_bytes(&s->bsp_leaves, sizeof(sl_bsp_leaf)) +
                       arr_bytes(&s->bsp_leaf_objects, 4) + arr_bytes(&s->bsp_pvs, 1) +
                       arr_bytes(&s->materials, sizeof(sl_material_rec)) + arr_bytes(&s->material_text, 1) +
                       arr_bytes(&s->object_materials, 4) + arr_bytes(&s->uvs, 4) + arr_bytes(&s->mesh_uvs, 1);
    st->bounds = sl_scene_bounds(s);
}

/* ---- validation of directly filled scenes (.slscene loader) ---- */

/* Materials, their texture bytes, object material ids, UV arrays and the see-through rules of
 * scene.h, for a scene filled by the reader (objects already checked against the meshes). */
static sl_status validate_materials(const struct sl_scene_t *s, sl_error *err)
{
    const sl_material_rec *mat = (const sl_material_rec *)s->materials.data;
    const char *text = (const char *)s->material_text.data;
    uint64_t at = 0; /* the texture bytes hold exactly the paths, in material order, each + NUL */
    for (size_t i = 0; i < s->materials.count; i++) {
        const char *why = sl_material_rec_problem(&mat[i]);
        if (why)
            return sl_fail(err, SL_ERROR_FORMAT, "material %zu: %s", i + 1, why);
        if (mat[i].reserved)
            return sl_fail(err, SL_ERROR_FORMAT, "material %zu: reserved field is not zero", i + 1);
        if (mat[i].texture_length == 0) {
            if (mat[i].texture_offset)
                return sl_fail(err, SL_ERROR_FORMAT, "material %zu: no texture but a texture offset of %u", i + 1,
                               mat[i].texture_offset);
            continue;
        }
        if (mat[i].texture_offset != at)
            return sl_fail(err, SL_ERROR_FORMAT, "material %zu: texture offset %u, expected %llu (paths in material order)",
                           i + 1, mat[i].texture_offset, (unsigned long long)at);
        if ((uint64_t)mat[i].texture_length + 1 > s->material_text.count - at)
            return sl_fail(err, SL_ERROR_FORMAT, "material %zu: texture path of %u bytes at byte %llu runs past the %zu bytes of paths",
                           i + 1, mat[i].texture_length, (unsigned long long)at, s->material_text.count);
        const char *p = text + at;
        if ((why = sl_texture_path_problem(p, mat[i].texture_length)) != NULL)
            return sl_fail(err, SL_ERROR_FORMAT, "material %zu: texture path at byte %llu %s", i + 1, (unsigned long long)at, why);
        if (p[mat[i].texture_length] != 0)
            return sl_fail(err, SL_ERROR_FORMAT, "material %zu: texture path at byte %llu is not followed by a NUL", i + 1,
                           (unsigned long long)at);
        at += (uint64_t)mat[i].texture_length + 1;
    }
    if (at != s->material_text.count)
        return sl_fail(err, SL_ERROR_FORMAT, "texture paths: %llu bytes used by the materials, section has %zu",
                       (unsigned long long)at, s->material_text.count);
    if (s->object_materials.count && s->object_materials.count != s->objects.count)
        return sl_fail(err, SL_ERROR_FORMAT, "object materials: %zu entries for %zu objects", s->object_materials.count,
                       s->objects.count);
    const sl_object_rec *o = sl_scene_objects(s);
    for (size_t i = 0; i < s->objects.count; i++) {
        uint32_t m = i < s->object_materials.count ? SL_AT(s->object_materials, uint32_t, i) : 0;
        if (m > s->materials.count)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: material %u out of range (%zu materials)", i, m,
                           s->materials.count);
        bool see = (o[i].flags & SL_OBJECT_SEE_THROUGH) != 0;
        if (m && mat[m - 1].alpha_mode != SL_ALPHA_OPAQUE && !see)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: material %u is alpha-tested or blended but the object is not see-through",
                           i, m);
        if (see && (o[i].flags & SL_OBJECT_OCCLUDER))
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: flagged both see-through and occluder", i);
    }
    if (s->uvs.count && s->uvs.count != 2 * (s->positions.count / 3))
        return sl_fail(err, SL_ERROR_FORMAT, "uvs: %zu floats for %zu vertices (2 per vertex)", s->uvs.count,
                       s->positions.count / 3);
    if (s->mesh_uvs.count && (s->mesh_uvs.count != s->meshes.count || !s->uvs.count))
        return sl_fail(err, SL_ERROR_FORMAT, "mesh uv flags: %zu entries for %zu meshes%s", s->mesh_uvs.count,
                       s->meshes.count, s->uvs.count ? "" : " and no uvs");
    if (s->uvs.count && !s->mesh_uvs.count)
        return sl_fail(err, SL_ERROR_FORMAT, "uvs without mesh uv flags");
    const uint8_t *mu = (const uint8_t *)s->mesh_uvs.data;
    for (size_t i = 0; i < s->mesh_uvs.count; i++)
        if (mu[i] > 1)
            return sl_fail(err, SL_ERROR_FORMAT, "mesh %zu: uv flag %u is neither 0 nor 1", i, mu[i]);
    const float *uv = (const float *)s->uvs.data;
    for (size_t i = 0; i < s->uvs.count; i++)
        if (!isfinite(uv[i]))
            return sl_fail(err, SL_ERROR_FORMAT, "vertex %zu: uv.%c is not finite", i / 2, "uv"[i % 2]);
    return SL_OK;
}

void sl_scene_recompute_bounds(struct sl_scene_t *s)
{
    for (size_t i = 0; i < s->objects.count; i++)
        sl_scene_update_object_bounds(s, (uint32_t)i);
}

sl_status sl_scene_validate(const struct sl_scene_t *s, sl_error *err)
{
    if (s->positions.count % 3 || s->normals.count != s->positions.count || s->indices.count % 3)
        return sl_fail(err, SL_ERROR_FORMAT, "vertex/normal/index array sizes are inconsistent");
    uint64_t nv = s->positions.count / 3, ni = s->indices.count;
    const float *pos = sl_scene_positions(s), *nrm = (const float *)s->normals.data;
    const sl_mesh_rec *m = sl_scene_meshes(s);
    for (uint64_t i = 0; i < 3 * nv; i++)
        if (!isfinite(pos[i]) || !isfinite(nrm[i])) {
            /* say which attribute and component, and where the vertex belongs */
            uint64_t v = i / 3;
            bool p = !isfinite(pos[i]);
            float x = p ? pos[i] : nrm[i];
            char where[96] = "";
            for (size_t k = 0; k < s->meshes.count; k++)
                if (v >= m[k].first_vertex && v - m[k].first_vertex < m[k].vertex_count) {
                    size_t obj = SIZE_MAX;
                    const sl_object_rec *o = sl_scene_objects(s);
                    for (size_t j = 0; j < s->objects.count && obj == SIZE_MAX; j++)
                        if (o[j].mesh == k)
                            obj = j;
                    if (obj != SIZE_MAX)
                        snprintf(where, sizeof where, " (object %zu, mesh %zu vertex %llu)", obj, k,
                                 (unsigned long long)(v - m[k].first_vertex));
                    else
                        snprintf(where, sizeof where, " (mesh %zu vertex %llu)", k, (unsigned long long)(v - m[k].first_vertex));
                    break;
                }
            return sl_fail(err, SL_ERROR_FORMAT, "vertex %llu%s: %s.%c is %s", (unsigned long long)v, where,
                           p ? "position" : "normal", "xyz"[i % 3], isnan(x) ? "NaN" : x > 0 ? "+inf" : "-inf");
        }
    const uint32_t *idx = sl_scene_indices(s);
    for (size_t i = 0; i < s->meshes.count; i++) {
        if (m[i].first_vertex > nv || m[i].vertex_count > nv - m[i].first_vertex || m[i].first_index % 3 ||
            m[i].first_index > ni || 3ull * m[i].triangle_count > ni - m[i].first_index)
            return sl_fail(err, SL_ERROR_FORMAT, "mesh %zu: vertex or index range out of bounds", i);
        const uint32_t *mi = idx + m[i].first_index;
        for (uint64_t k = 0; k < 3ull * m[i].triangle_count; k++)
            if (mi[k] >= m[i].vertex_count)
                return sl_fail(err, SL_ERROR_FORMAT, "mesh %zu: triangle %llu has index %u >= %u vertices", i,
                               (unsigned long long)(k / 3), mi[k], m[i].vertex_count);
    }
    const sl_affine *tr = sl_scene_transforms(s);
    for (size_t i = 0; i < s->transforms.count; i++)
        if (!affine_finite(&tr[i]))
            return sl_fail(err, SL_ERROR_FORMAT, "transform %zu: not finite", i);
    const sl_object_rec *o = sl_scene_objects(s);
    if (s->bounds.count != s->objects.count)
        return sl_fail(err, SL_ERROR_FORMAT, "object bounds count differs from object count");
    for (size_t i = 0; i < s->objects.count; i++) {
        if (o[i].mesh >= s->meshes.count)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: mesh %u out of range", i, o[i].mesh);
        if (o[i].transform != SL_NONE && o[i].transform >= s->transforms.count)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: transform %u out of range", i, o[i].transform);
    }
    sl_status mst = validate_materials(s, err);
    if (mst != SL_OK)
        return mst;
    const float *fxy = (const float *)s->footprint_xy.data;
    for (size_t i = 0; i < s->footprints.count; i++) {
        const sl_footprint_rec *f = &SL_AT(s->footprints, sl_footprint_rec, i);
        if (f->vertex_count < 3 || (uint64_t)f->first_vertex + f->vertex_count > s->footprint_xy.count / 2)
            return sl_fail(err, SL_ERROR_FORMAT, "footprint %zu: vertex range out of bounds", i);
        if (!isfinite(f->base_z) || !isfinite(f->roof_z) || !(f->roof_z > f->base_z))
            return sl_fail(err, SL_ERROR_FORMAT, "footprint %zu: bad heights", i);
        if (f->object != SL_NONE && f->object >= s->objects.count)
            return sl_fail(err, SL_ERROR_FORMAT, "footprint %zu: object %u out of range", i, f->object);
        if (f->object != SL_NONE && (o[f->object].flags & SL_OBJECT_SEE_THROUGH))
            return sl_fail(err, SL_ERROR_FORMAT, "footprint %zu: object %u is see-through (it never occludes)", i, f->object);
        for (uint32_t k = 0; k < 2 * f->vertex_count; k++)
            if (!isfinite(fxy[2 * (size_t)f->first_vertex + k]))
                return sl_fail(err, SL_ERROR_FORMAT, "footprint %zu: vertex not finite", i);
    }
    for (size_t i = 0; i < s->occluders.count; i++) {
        const sl_occluder_rec *r = &SL_AT(s->occluders, sl_occluder_rec, i);
        if (r->mesh >= s->meshes.count || (r->transform != SL_NONE && r->transform >= s->transforms.count) ||
            (r->object != SL_NONE && r->object >= s->objects.count))
            return sl_fail(err, SL_ERROR_FORMAT, "occluder %zu: reference out of range", i);
        if (r->object != SL_NONE && (o[r->object].flags & SL_OBJECT_SEE_THROUGH))
            return sl_fail(err, SL_ERROR_FORMAT, "occluder %zu: object %u is see-through (it never occludes)", i, r->object);
    }
    if (s->has_terrain) {
        size_t n;
        if (s->terrain_nx < 2 || s->terrain_ny < 2 || !sl_mul_size(s->terrain_nx, s->terrain_ny, &n) ||
            n != s->terrain_heights.count || !(s->terrain_cell > 0) || !isfinite(s->terrain_cell) ||
            !isfinite(s->terrain_origin_x) || !isfinite(s->terrain_origin_y))
            return sl_fail(err, SL_ERROR_FORMAT, "terrain: bad dimensions");
        const float *h = (const float *)s->terrain_heights.data;
        for (size_t i = 0; i < n; i++)
            if (!isfinite(h[i]))
                return sl_fail(err, SL_ERROR_FORMAT, "terrain: sample %zu not finite", i);
    }
    const float *sxy = (const float *)s->street_xy.data;
    for (size_t i = 0; i < s->street_xy.count; i++)
        if (!isfinite(sxy[i]))
            return sl_fail(err, SL_ERROR_FORMAT, "street polygon vertex %zu not finite", i / 2);
    for (size_t i = 0; i < s->street_polys.count; i++) {
        const sl_polygon_rec *p = &SL_AT(s->street_polys, sl_polygon_rec, i);
        if (p->vertex_count < 3 || (uint64_t)p->first_vertex + p->vertex_count > s->street_xy.count / 2)
            return sl_fail(err, SL_ERROR_FORMAT, "street polygon %zu: vertex range out of bounds", i);
    }
    const sl_street_node *sn = (const sl_street_node *)s->street_nodes.data;
    for (size_t i = 0; i < s->street_nodes.count; i++)
        if (!isfinite(sn[i].x) || !isfinite(sn[i].y))
            return sl_fail(err, SL_ERROR_FORMAT, "street node %zu not finite", i);
    const sl_street_edge *se = (const sl_street_edge *)s->street_edges.data;
    for (size_t i = 0; i < s->street_edges.count; i++)
        if (se[i].a >= s->street_nodes.count || se[i].b >= s->street_nodes.count)
            return sl_fail(err, SL_ERROR_FORMAT, "street edge %zu: node out of range (node %u, %zu nodes)", i,
                           se[i].a >= s->street_nodes.count ? se[i].a : se[i].b, s->street_nodes.count);
        else if (!isfinite(se[i].width))
            return sl_fail(err, SL_ERROR_FORMAT, "street edge %zu: width is %s", i, isnan(se[i].width) ? "NaN" : "infinite");
    if (s->has_bsp) {
        sl_bsp_view v;
        sl_scene_bsp((sl_scene)s, &v);
        if (v.pvs && s->bsp_pvs.count != (size_t)v.cluster_count * v.cluster_bytes)
            return sl_fail(err, SL_ERROR_FORMAT, "bsp vis: size mismatch");
        sl_status st = validate_bsp(&v, (uint32_t)s->objects.count, SL_ERROR_FORMAT, err);
        if (st != SL_OK)
            return st;
    }
    return SL_OK;
}

/* The oracles' and the cullers' domain (declared in scene.h): moved here from truth/oracle.c so that
 * the cullers (run time) use it from below. */
bool sl_oracle_in_domain(sl_scene scene, sl_vec3 eye, int32_t *leaf)
{
    if (leaf)
        *leaf = -1;
    sl_bsp_view bsp;
    if (!scene || !sl_scene_bsp(scene, &bsp) || bsp.leaf_count == 0)
        return true;
    int32_t l = sl_scene_bsp_find_leaf(scene, eye);
    if (leaf)
        *leaf = l;
    /* without nodes there is no space to be outside of (one leaf holds everything) */
    if (bsp.node_count == 0 || l < 0 || (uint32_t)l >= bsp.leaf_count)
        return true;
    return bsp.leaves[l].cluster >= 0;
}

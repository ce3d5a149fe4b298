/* vfc: hierarchical view-frustum culling over the object BVH, the baseline every method beats.
 *
 * U. Assarsson and T. Moeller, "Optimized View Frustum Culling Algorithms for Bounding Boxes",
 * Journal of Graphics Tools 5(1), 2000: the box is tested against each plane with its p/n corner
 * (section 3), a node wholly inside a plane passes the plane's bit down so children skip it (plane
 * masking, section 4.1), and the plane that rejected a node last frame is tried first this frame
 * (plane coherency, section 4.2).
 *
 * Object-level back-face rejection: a triangle is back-facing exactly when the eye lies behind its
 * plane, so an object whose every face plane has the eye behind it draws nothing when back faces
 * are culled (the oracle's default for SL_OBJECT_CLOSED_CONVEX objects). For a closed convex part
 * this happens exactly when the eye is inside it. The face planes are collected per mesh in mesh
 * coordinates (at most MAX_FACE_PLANES distinct ones, else the mesh is not tested) and only objects
 * whose box contains the eye are tested, with the eye brought into mesh coordinates.
 *
 * Conservative: a box is rejected only when it lies beyond a plane by a small slack that covers
 * the float rounding of the planes; an object is dropped by back-face rejection only when the eye
 * is behind every face plane by a margin. */
#include "culler_internal.h"

#include "accel/bvh_internal.h"
#include "scene/scene_internal.h"

#include <math.h>

#define MAX_FACE_PLANES 64
#define NO_PLANE 0xff

typedef struct vfc_config {
    bool plane_masks, coherence, backface;
    uint32_t leaf_size;
} vfc_config;

typedef struct vfc_state {
    sl_allocator alloc;
    sl_scene scene;
    vfc_config cfg;
    sl_bvh bvh;
    bool bvh_owned;           /* false: the shared handle's (sl_cull_extras.accel), never refitted here */
    uint8_t *node_last;       /* per node slot: plane that last rejected it, or NO_PLANE */
    uint32_t node_slots;
    uint8_t *object_last;     /* per object slot of the BVH (leaf order) */
    uint32_t object_count;
    uint32_t *sort_scratch;   /* object_count ids */
    /* face planes per mesh, in mesh coordinates: planes[first[m] .. first[m]+count[m]) */
    uint32_t mesh_count;
    uint32_t *plane_first, *plane_count;
    sl_plane *planes;
    size_t plane_total;
    float *plane_margin;      /* per mesh: how far behind every plane the eye must be */
} vfc_state;

static const char g_help[] =
    "plane_masks=BOOL (default true): skip the planes a parent box is wholly inside\n"
    "coherence=BOOL (default true): test first the plane that rejected a node last frame\n"
    "backface=BOOL (default true): drop closed convex objects (SL_OBJECT_CLOSED_CONVEX) whose faces all face away\n"
    "leaf_size=1..16 (default 4): most objects per BVH leaf\n";

static sl_status vfc_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    vfc_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_opts_bool(o, "plane_masks", true, &c->plane_masks, err)) != SL_OK ||
        (st = sl_opts_bool(o, "coherence", true, &c->coherence, err)) != SL_OK ||
        (st = sl_opts_bool(o, "backface", true, &c->backface, err)) != SL_OK ||
        (st = sl_opts_u32(o, "leaf_size", SL_BVH_DEFAULT_LEAF_SIZE, 1, SL_BVH_MAX_LEAF_SIZE, &c->leaf_size, err)) != SL_OK)
        return st;
    return SL_OK;
}

static void free_coherence(vfc_state *s)
{
    sl_free(&s->alloc, s->node_last, s->node_slots);
    s->node_last = NULL;
    s->node_slots = 0;
}

/* (Re)size the coherence hints to the current tree; all hints start empty. */
static sl_status reset_coherence(vfc_state *s, sl_error *err)
{
    const struct sl_bvh_t *b = s->bvh;
    if (s->node_slots != b->node_slots) {
        free_coherence(s);
        if (b->node_slots) {
            s->node_last = sl_alloc(&s->alloc, b->node_slots);
            if (!s->node_last)
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "vfc: out of memory for %u node hints", b->node_slots);
        }
        s->node_slots = b->node_slots;
    }
    if (s->node_last)
        memset(s->node_last, NO_PLANE, s->node_slots);
    if (s->object_last)
        memset(s->object_last, NO_PLANE, s->object_count);
    return SL_OK;
}

/* Distinct face planes of every mesh used by a closed convex object. */
static sl_status collect_face_planes(vfc_state *s, sl_error *err)
{
    const struct sl_scene_t *sc = s->scene;
    uint32_t nm = sl_scene_mesh_count(s->scene), no = sl_scene_object_count(s->scene);
    s->mesh_count = nm;
    s->plane_first = sl_calloc(&s->alloc, nm ? nm : 1, sizeof(uint32_t));
    s->plane_count = sl_calloc(&s->alloc, nm ? nm : 1, sizeof(uint32_t));
    s->plane_margin = sl_calloc(&s->alloc, nm ? nm : 1, sizeof(float));
    if (!s->plane_first || !s->plane_count || !s->plane_margin)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "vfc: out of memory for %u meshes", nm);
    const sl_object_rec *objects = sl_scene_objects(sc);
    const sl_mesh_rec *meshes = sl_scene_meshes(sc);
    const float *pos = sl_scene_positions(sc);
    const uint32_t *idx = sl_scene_indices(sc);
    /* mark meshes to examine: plane_count = 1 as a flag until filled in */
    for (uint32_t i = 0; i < no; i++)
        if (objects[i].flags & SL_OBJECT_CLOSED_CONVEX)
            s->plane_count[objects[i].mesh] = 1;
    sl_array planes = {0};
    for (uint32_t m = 0; m < nm; m++) {
        if (!s->plane_count[m])
            continue;
        s->plane_count[m] = 0;
        const sl_mesh_rec *mr = &meshes[m];
        const float *p = pos + 3 * mr->first_vertex;
        const uint32_t *t = idx + mr->first_index;
        size_t first = planes.count;
        bool too_many = false;
        for (uint32_t k = 0; k < mr->triangle_count && !too_many; k++) {
            const float *a = p + 3 * t[3 * k], *b = p + 3 * t[3 * k + 1], *c = p + 3 * t[3 * k + 2];
            double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
            double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
            double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (!(len > 0))
                continue; /* a degenerate triangle is never drawn */
            sl_plane pl = {(float)(n[0] / len), (float)(n[1] / len), (float)(n[2] / len), 0};
            pl.d = (float)-((double)pl.a * a[0] + (double)pl.b * a[1] + (double)pl.c * a[2]);
            bool dup = false;
            for (size_t q = first; q < planes.count && !dup; q++) {
                const sl_plane *o = &SL_AT(planes, sl_plane, q);
                dup = fabsf(o->a - pl.a) < 1e-5f && fabsf(o->b - pl.b) < 1e-5f && fabsf(o->c - pl.c) < 1e-5f &&
                      fabsf(o->d - pl.d) < 1e-5f * (1.0f + fabsf(pl.d));
            }
            if (dup)
                continue;
            if (planes.count - first == MAX_FACE_PLANES)
                too_many = true;
            else if (!sl_array_push(&s->alloc, &planes, sizeof pl, &pl, 1)) {
                sl_array_free(&s->alloc, &planes, sizeof(sl_plane));
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "vfc: out of memory for face planes");
            }
        }
        if (too_many) {
            planes.count = first; /* not cheap: this mesh is not tested */
            continue;
        }
        s->plane_first[m] = (uint32_t)first;
        s->plane_count[m] = (uint32_t)(planes.count - first);
        /* the margin covers the rounding of the planes: relative to the mesh's size and offset */
        const sl_aabb *bb = &mr->bounds;
        float ext = fmaxf(fmaxf(fabsf(bb->min.x), fabsf(bb->max.x)), fmaxf(fmaxf(fabsf(bb->min.y), fabsf(bb->max.y)),
                                                                            fmaxf(fabsf(bb->min.z), fabsf(bb->max.z))));
        s->plane_margin[m] = 1e-5f * (1.0f + ext);
    }
    s->planes = planes.data;
    s->plane_total = planes.cap;
    return SL_OK;
}

static void vfc_destroy(void *state)
{
    vfc_state *s = state;
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    if (s->bvh_owned)
        sl_bvh_destroy(s->bvh);
    free_coherence(s);
    sl_free(a, s->object_last, s->object_count);
    sl_free(a, s->sort_scratch, (size_t)s->object_count * sizeof(uint32_t));
    uint32_t nm = s->mesh_count ? s->mesh_count : 1;
    sl_free(a, s->plane_first, nm * sizeof(uint32_t));
    sl_free(a, s->plane_count, nm * sizeof(uint32_t));
    sl_free(a, s->plane_margin, nm * sizeof(float));
    sl_free(a, s->planes, s->plane_total * sizeof(sl_plane));
    sl_free(a, s, sizeof *s);
}

static sl_status vfc_create(sl_scene scene, const void *config, const sl_cull_extras *extras, const sl_allocator *alloc,
                            void **state, sl_error *err)
{
    vfc_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "vfc: out of memory");
    s->alloc = *alloc;
    s->scene = scene;
    s->cfg = *(const vfc_config *)config;
    sl_status st = sl_cull_object_bvh(scene, extras, s->cfg.leaf_size, alloc, &s->bvh, &s->bvh_owned, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "vfc");
        vfc_destroy(s);
        return st;
    }
    s->object_count = sl_scene_object_count(scene);
    size_t n = s->object_count;
    s->object_last = sl_alloc(alloc, n ? n : 1);
    s->sort_scratch = sl_alloc(alloc, (n ? n : 1) * sizeof(uint32_t));
    if (!s->object_last || !s->sort_scratch) {
        vfc_destroy(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "vfc: out of memory for %zu objects", n);
    }
    if ((st = reset_coherence(s, err)) != SL_OK || (s->cfg.backface && (st = collect_face_planes(s, err)) != SL_OK)) {
        vfc_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status vfc_scene_changed(void *state, sl_error *err)
{
    vfc_state *s = state;
    if (!s->bvh_owned)
        return reset_coherence(s, err); /* the handle's owner refitted the tree (accel.h) */
    sl_status st = sl_bvh_refit(s->bvh, s->scene, err);
    bool rebuilt = false;
    if (st == SL_OK)
        st = sl_bvh_rebuild_if_degraded(s->bvh, s->scene, 0, &rebuilt, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "vfc");
        return st;
    }
    /* refit keeps the slots, so old hints are still about the same nodes; a rebuild starts afresh */
    return rebuilt ? reset_coherence(s, err) : SL_OK;
}

/* Classify box b against the planes in mask: returns -1 when it lies outside one (recorded in
 * *last), else the mask of the planes it straddles. The hinted plane goes first. */
static inline int classify(const sl_plane *pl, const float *slack, const sl_aabb *b, uint32_t mask, uint8_t *last,
                           bool coherence, bool masks)
{
    if (coherence && *last != NO_PLANE && (mask & (1u << *last)) &&
        sl_frustum_plane_rejects(&pl[*last], slack[*last], b))
        return -1;
    /* the shared classifier (core/frustum_classify.h) */
    return sl_frustum_classify_box(pl, slack, b, mask, masks, last);
}

/* True when the eye is behind every face plane of object `id` (it draws nothing). */
static bool faces_away(const vfc_state *s, uint32_t id, const sl_vec3 *eye)
{
    const struct sl_scene_t *sc = s->scene;
    const sl_object_rec *o = &sl_scene_objects(sc)[id];
    uint32_t m = o->mesh, n = s->plane_count[m];
    if (n == 0)
        return false;
    double e[3] = {eye->x, eye->y, eye->z};
    if (o->transform != SL_NONE) {
        /* eye in mesh coordinates: inverse of the 3x4 affine by cofactors */
        const float *t = sl_scene_transforms(sc)[o->transform].m;
        double a = t[0], b = t[1], c = t[2], d = t[4], f = t[5], g = t[6], h = t[8], i = t[9], k = t[10];
        double det = a * (f * k - g * i) - b * (d * k - g * h) + c * (d * i - f * h);
        if (!(fabs(det) > 1e-12))
            return false;
        double x = e[0] - t[3], y = e[1] - t[7], z = e[2] - t[11];
        e[0] = ((f * k - g * i) * x - (b * k - c * i) * y + (b * g - c * f) * z) / det;
        e[1] = (-(d * k - g * h) * x + (a * k - c * h) * y - (a * g - c * d) * z) / det;
        e[2] = ((d * i - f * h) * x - (a * i - b * h) * y + (a * f - b * d) * z) / det;
    }
    const sl_plane *pl = s->planes + s->plane_first[m];
    double margin = s->plane_margin[m];
    for (uint32_t q = 0; q < n; q++)
        if (!(pl[q].a * e[0] + pl[q].b * e[1] + pl[q].c * e[2] + pl[q].d < -margin))
            return false;
    return true;
}

static sl_status vfc_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    (void)err;
    vfc_state *s = state;
    const struct sl_bvh_t *b = s->bvh;
    double t0 = sl_now();
    uint32_t k = 0;
    if (b->node_slots == 0) {
        *count = 0;
        sl_cull_phase(stats, "traverse", sl_cull_ms(t0, sl_now()));
        return SL_OK;
    }
    sl_frustum fr = view->frustum;
    float slack[6];
    for (int i = 0; i < 6; i++)
        slack[i] = sl_margin_plane_slack(fr.planes[i].d);
    /* back-face rejection is for a perspective eye; an orthographic view always sees some front face */
    bool backface = s->cfg.backface && s->planes && view->projection == SL_PERSPECTIVE;
    const sl_vec3 eye = view->eye;
    const sl_aabb *const obj_box = b->object_bounds;
    const sl_bvh_node *nodes = b->nodes;
    const sl_object_rec *objects = sl_scene_objects(s->scene);
    struct {
        uint32_t node, mask;
    } stack[SL_BVH_MAX_DEPTH + 1];
    uint32_t sp = 0, ni = 0, mask = 0x3f;
    uint64_t visited = 0, tested = 0;
    for (;;) {
        const sl_bvh_node *n = &nodes[ni];
        visited++;
        int r = mask ? classify(fr.planes, slack, &n->box, mask, &s->node_last[ni], s->cfg.coherence, s->cfg.plane_masks)
                     : 0;
        if (r >= 0) {
            uint32_t m = (uint32_t)r;
            if (n->count == 0) {
                stack[sp].node = n->first + 1;
                stack[sp].mask = m;
                sp++;
                ni = n->first;
                mask = m;
                continue;
            }
            for (uint32_t j = n->first; j < n->first + n->count; j++) {
                if (m) {
                    tested++;
                    if (classify(fr.planes, slack, &obj_box[j], m, &s->object_last[j], s->cfg.coherence, false) < 0)
                        continue;
                }
                uint32_t id = b->objects[j];
                if (backface && (objects[id].flags & SL_OBJECT_CLOSED_CONVEX)) {
                    const sl_aabb *ob = &obj_box[j];
                    if (eye.x >= ob->min.x && eye.x <= ob->max.x && eye.y >= ob->min.y && eye.y <= ob->max.y &&
                        eye.z >= ob->min.z && eye.z <= ob->max.z) {
                        tested++;
                        if (faces_away(s, id, &eye))
                            continue;
                    }
                }
                out[k++] = id;
            }
        }
        if (sp == 0)
            break;
        sp--;
        ni = stack[sp].node;
        mask = stack[sp].mask;
    }
    double t1 = sl_now();
    sl_cull_sort_ids(out, k, s->sort_scratch);
    double t2 = sl_now();
    stats->nodes_visited = visited;
    stats->objects_tested = tested;
    sl_cull_phase(stats, "traverse", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "sort", sl_cull_ms(t1, t2));
    *count = k;
    return SL_OK;
}

const sl_cull_method sl_cull_method_vfc = {
    .name = "vfc",
    .suits = "any scene: the baseline, and the fallback where no occluder helps",
    .summary = "hierarchical view-frustum culling over the object BVH with plane masks, plane coherence and "
               "closed-object back-face rejection (Assarsson & Moeller 2000)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(vfc_config),
    .configure = vfc_configure,
    .create_with = vfc_create,
    .cull = vfc_cull,
    .scene_changed = vfc_scene_changed,
    .destroy = vfc_destroy,
};

/* Updating a bake after an edit of the scene (sl_pvs_update, `sightline pvs update`): re-bake only
 * the view cells an edit can affect and copy the others' sets from the old file, so that the file
 * is the one a full re-bake of the edited scene writes, byte for byte. docs/pvs.md ("Updating a
 * bake") has the rule and the argument; in short:
 *
 *  1. The two scenes are matched object by object and footprint by footprint by content (mesh
 *     positions and indices, kind, flags, transform, box; a footprint's polygon, heights and the
 *     content of its object): unmatched old objects were removed (or moved away), unmatched new
 *     ones added (or moved there). The terrain, the streets, the BSP and the mesh occluders must be
 *     unchanged, and so must the view cells (the caller makes them for the edited scene as the full
 *     bake would): otherwise the update is refused.
 *  2. The zone: the changed footprints, old and new, and every footprint linked to them by touching
 *     boxes (transitively; whole merged groups, which `sample` erodes as one, and `adjustable`'s runs
 *     of touching pieces), with their objects' boxes, and the boxes of the other changed objects.
 *     Everything outside the zone is the same in both scenes (the ids aside).
 *  3. A cell is re-baked when (a) its old set holds a removed object or an object of the zone, or
 *     (b) the probe (adjustable's coarsest level of disks for the cell, with the occluders outside
 *     the zone only: sl_adj_probe_cell) cannot hide every box of the zone. Otherwise every point of
 *     the cell has every sight line into the zone blocked by occluders that did not change: what
 *     the cell sees is the same in both scenes, and its old set, with the ids renumbered, is copied.
 *     And (c): a cell whose highest footprint base at or below its lowest eye the edit changed
 *     (sl_cell_floor: which footprints occlude and which objects get stand-ins depends on it).
 *
 * Methods: `adjustable` and `sample` (their sets depend on the footprints, the boxes and the cells
 * only); the file's method and effective options are re-used, so the metadata is the full bake's. */
#include "pvs_internal.h"

#include "scene/scene_internal.h"

#include <omp.h>
#include <stdlib.h>
#include <time.h>

#define ZONE_TOUCH 0.05 /* metres: boxes nearer than this count as touching */

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* ---- content hashes ---- */

static uint64_t hash_mesh(sl_scene s, uint32_t m)
{
    sl_mesh_view v = sl_scene_mesh(s, m);
    uint32_t n[2] = {v.vertex_count, v.triangle_count};
    uint64_t h = sl_hash64(n, sizeof n, 0x4d455348ull);
    if (v.vertex_count)
        h = sl_hash64(v.positions, (size_t)v.vertex_count * 3 * sizeof(float), h);
    if (v.triangle_count)
        h = sl_hash64(v.indices, (size_t)v.triangle_count * 3 * sizeof(uint32_t), h);
    return h;
}

/* Per object: its mesh's content, kind, flags, transform and world box (dynamic ones too: the
 * methods read every object's box). */
static sl_status hash_objects(sl_scene s, const sl_allocator *a, uint64_t **out, sl_error *err)
{
    uint32_t nm = sl_scene_mesh_count(s), no = sl_scene_object_count(s);
    uint64_t *mh = sl_alloc(a, ((size_t)nm + 1) * sizeof *mh);
    uint64_t *oh = sl_alloc(a, ((size_t)no + 1) * sizeof *oh);
    if (!mh || !oh) {
        sl_free(a, mh, ((size_t)nm + 1) * sizeof *mh);
        sl_free(a, oh, ((size_t)no + 1) * sizeof *oh);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    for (uint32_t m = 0; m < nm; m++)
        mh[m] = hash_mesh(s, m);
    for (uint32_t o = 0; o < no; o++) {
        sl_object_view v = sl_scene_object(s, o);
        uint64_t h = v.mesh < nm ? mh[v.mesh] : 0;
        uint32_t u[2] = {v.kind, v.flags};
        h = sl_hash64(u, sizeof u, h);
        h = sl_hash64(v.transform.m, sizeof v.transform.m, h);
        h = sl_hash64(&v.bounds, sizeof v.bounds, h);
        oh[o] = h;
    }
    sl_free(a, mh, ((size_t)nm + 1) * sizeof *mh);
    *out = oh;
    return SL_OK;
}

static uint64_t hash_footprint(sl_scene s, uint32_t f, const uint64_t *objh)
{
    sl_footprint_view v = sl_scene_footprint(s, f);
    uint64_t h = sl_hash64(&v.vertex_count, sizeof v.vertex_count, 0x464f4f54ull);
    h = sl_hash64(v.xy, (size_t)v.vertex_count * 2 * sizeof(float), h);
    float z[2] = {v.base_z, v.roof_z};
    h = sl_hash64(z, sizeof z, h);
    uint64_t oh = v.object != SL_NONE && v.object < sl_scene_object_count(s) ? objh[v.object] : 0;
    return sl_hash64(&oh, sizeof oh, h);
}

/* What must not change: the terrain, the streets (polygons and graph), the BSP, the mesh occluders. */
static uint64_t hash_fixed(sl_scene scene, int part)
{
    const struct sl_scene_t *s = scene;
    uint64_t h = sl_hash64(&part, sizeof part, 0x46495845ull);
    if (part == 0) { /* terrain */
        uint32_t t[3] = {s->has_terrain ? 1u : 0u, s->has_terrain ? s->terrain_nx : 0, s->has_terrain ? s->terrain_ny : 0};
        h = sl_hash64(t, sizeof t, h);
        if (s->has_terrain) {
            float g[3] = {s->terrain_origin_x, s->terrain_origin_y, s->terrain_cell};
            h = sl_hash64(g, sizeof g, h);
            h = sl_hash64(s->terrain_heights.data, s->terrain_heights.count * sizeof(float), h);
        }
    } else if (part == 1) { /* streets */
        uint64_t n[4] = {s->street_polys.count, s->street_xy.count, s->street_nodes.count, s->street_edges.count};
        h = sl_hash64(n, sizeof n, h);
        h = sl_hash64(s->street_polys.data, s->street_polys.count * sizeof(sl_polygon_rec), h);
        h = sl_hash64(s->street_xy.data, s->street_xy.count * sizeof(float), h);
        h = sl_hash64(s->street_nodes.data, s->street_nodes.count * sizeof(sl_street_node), h);
        h = sl_hash64(s->street_edges.data, s->street_edges.count * sizeof(sl_street_edge), h);
    } else if (part == 2) { /* BSP */
        uint32_t b[3] = {s->has_bsp ? 1u : 0u, s->has_bsp ? s->bsp_cluster_count : 0, s->has_bsp ? s->bsp_cluster_bytes : 0};
        h = sl_hash64(b, sizeof b, h);
        if (s->has_bsp) {
            uint64_t n[5] = {s->bsp_planes.count, s->bsp_nodes.count, s->bsp_leaves.count, s->bsp_leaf_objects.count,
                             s->bsp_pvs.count};
            h = sl_hash64(n, sizeof n, h);
            h = sl_hash64(s->bsp_planes.data, s->bsp_planes.count * sizeof(sl_plane), h);
            h = sl_hash64(s->bsp_nodes.data, s->bsp_nodes.count * sizeof(sl_bsp_node), h);
            h = sl_hash64(s->bsp_leaves.data, s->bsp_leaves.count * sizeof(sl_bsp_leaf), h);
            h = sl_hash64(s->bsp_leaf_objects.data, s->bsp_leaf_objects.count * sizeof(uint32_t), h);
            h = sl_hash64(s->bsp_pvs.data, s->bsp_pvs.count, h);
        }
    } else { /* mesh occluders */
        uint32_t no = sl_scene_occluder_count(scene);
        h = sl_hash64(&no, sizeof no, h);
        for (uint32_t i = 0; i < no; i++) {
            sl_occluder_view v = sl_scene_occluder(scene, i);
            h = sl_hash64(&v.transform, sizeof v.transform, sl_hash64(&v.mesh, sizeof v.mesh, h));
            h = hash_mesh(scene, v.mesh) ^ h;
        }
    }
    return h;
}

/* ---- matching by content ---- */

typedef struct hpair {
    uint64_t h;
    uint32_t i;
} hpair;

static int cmp_hpair(const void *x, const void *y)
{
    const hpair *a = x, *b = y;
    if (a->h != b->h)
        return a->h < b->h ? -1 : 1;
    return a->i < b->i ? -1 : a->i > b->i;
}

/* new_of_old[o]: the new element with the same content as old element o (the k-th equal old one
 * goes to the k-th equal new one, in order), or SL_NONE; old_of_new likewise. */
static sl_status match(const uint64_t *oldh, uint32_t nold, const uint64_t *newh, uint32_t nnew, const sl_allocator *a,
                       uint32_t *new_of_old, uint32_t *old_of_new, sl_error *err)
{
    hpair *p = sl_alloc(a, ((size_t)nold + 1) * sizeof *p);
    uint32_t *used = sl_calloc(a, (size_t)nold + 1, sizeof *used);
    if (!p || !used) {
        sl_free(a, p, ((size_t)nold + 1) * sizeof *p);
        sl_free(a, used, ((size_t)nold + 1) * sizeof *used);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    for (uint32_t o = 0; o < nold; o++) {
        p[o] = (hpair){oldh[o], o};
        new_of_old[o] = SL_NONE;
    }
    qsort(p, nold, sizeof *p, cmp_hpair);
    for (uint32_t i = 0; i < nnew; i++) {
        old_of_new[i] = SL_NONE;
        size_t lo = 0, hi = nold; /* first pair with hash >= newh[i] */
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (p[mid].h < newh[i])
                lo = mid + 1;
            else
                hi = mid;
        }
        if (lo < nold && p[lo].h == newh[i]) {
            size_t k = lo + used[lo];
            if (k < nold && p[k].h == newh[i]) {
                used[lo]++;
                old_of_new[i] = p[k].i;
                new_of_old[p[k].i] = i;
            }
        }
    }
    sl_free(a, p, ((size_t)nold + 1) * sizeof *p);
    sl_free(a, used, ((size_t)nold + 1) * sizeof *used);
    return SL_OK;
}

/* ---- the zone ---- */

static sl_aabb footprint_box(sl_scene s, uint32_t f)
{
    sl_footprint_view v = sl_scene_footprint(s, f);
    sl_aabb b = {{INFINITY, INFINITY, v.base_z}, {-INFINITY, -INFINITY, v.roof_z}};
    for (uint32_t i = 0; i < v.vertex_count; i++) {
        b.min.x = fminf(b.min.x, v.xy[2 * i]), b.max.x = fmaxf(b.max.x, v.xy[2 * i]);
        b.min.y = fminf(b.min.y, v.xy[2 * i + 1]), b.max.y = fmaxf(b.max.y, v.xy[2 * i + 1]);
    }
    return b;
}

static bool boxes_touch2d(const sl_aabb *a, const sl_aabb *b, double tol)
{
    return a->min.x <= b->max.x + tol && b->min.x <= a->max.x + tol && a->min.y <= b->max.y + tol &&
           b->min.y <= a->max.y + tol;
}

typedef struct update_ctx {
    const sl_allocator *a;
    sl_scene olds, news;
    uint32_t nold, nnew, nfold, nfnew;
    uint64_t *oh_old, *oh_new, *fh_old, *fh_new;
    uint32_t *obj_new_of_old, *obj_old_of_new, *fp_new_of_old, *fp_old_of_new;
    uint8_t *old_flag;     /* per old object: 1 removed, 2 in the zone */
    uint8_t *fp_use;       /* per new footprint: outside the zone (the probe's occluders) */
    sl_array zone;         /* sl_aabb: the probe's boxes */
    uint32_t zone_footprints;
} update_ctx;

static void ctx_free(update_ctx *c)
{
    const sl_allocator *a = c->a;
    sl_free(a, c->oh_old, ((size_t)c->nold + 1) * sizeof(uint64_t));
    sl_free(a, c->oh_new, ((size_t)c->nnew + 1) * sizeof(uint64_t));
    sl_free(a, c->fh_old, ((size_t)c->nfold + 1) * sizeof(uint64_t));
    sl_free(a, c->fh_new, ((size_t)c->nfnew + 1) * sizeof(uint64_t));
    sl_free(a, c->obj_new_of_old, ((size_t)c->nold + 1) * sizeof(uint32_t));
    sl_free(a, c->obj_old_of_new, ((size_t)c->nnew + 1) * sizeof(uint32_t));
    sl_free(a, c->fp_new_of_old, ((size_t)c->nfold + 1) * sizeof(uint32_t));
    sl_free(a, c->fp_old_of_new, ((size_t)c->nfnew + 1) * sizeof(uint32_t));
    sl_free(a, c->old_flag, (size_t)c->nold + 1);
    sl_free(a, c->fp_use, (size_t)c->nfnew + 1);
    sl_array_free(a, &c->zone, sizeof(sl_aabb));
}

static bool zone_add(update_ctx *c, sl_aabb b) { return sl_array_push(c->a, &c->zone, sizeof b, &b, 1); }

/* Diff the scenes and make the zone; close: add the footprints that touch it (transitively).
 * weaken (testing): 3 leaves the touching footprints out even when close. */
static sl_status diff_scenes(update_ctx *c, bool close, uint32_t weaken, sl_pvs_update_stats *st, sl_error *err)
{
    const sl_allocator *a = c->a;
    sl_status s;
    if ((s = hash_objects(c->olds, a, &c->oh_old, err)) != SL_OK || (s = hash_objects(c->news, a, &c->oh_new, err)) != SL_OK)
        return s;
    c->fh_old = sl_alloc(a, ((size_t)c->nfold + 1) * sizeof(uint64_t));
    c->fh_new = sl_alloc(a, ((size_t)c->nfnew + 1) * sizeof(uint64_t));
    c->obj_new_of_old = sl_alloc(a, ((size_t)c->nold + 1) * sizeof(uint32_t));
    c->obj_old_of_new = sl_alloc(a, ((size_t)c->nnew + 1) * sizeof(uint32_t));
    c->fp_new_of_old = sl_alloc(a, ((size_t)c->nfold + 1) * sizeof(uint32_t));
    c->fp_old_of_new = sl_alloc(a, ((size_t)c->nfnew + 1) * sizeof(uint32_t));
    c->old_flag = sl_calloc(a, (size_t)c->nold + 1, 1);
    c->fp_use = sl_alloc(a, (size_t)c->nfnew + 1);
    if (!c->fh_old || !c->fh_new || !c->obj_new_of_old || !c->obj_old_of_new || !c->fp_new_of_old ||
        !c->fp_old_of_new || !c->old_flag || !c->fp_use)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    for (uint32_t f = 0; f < c->nfold; f++)
        c->fh_old[f] = hash_footprint(c->olds, f, c->oh_old);
    for (uint32_t f = 0; f < c->nfnew; f++)
        c->fh_new[f] = hash_footprint(c->news, f, c->oh_new);
    if ((s = match(c->oh_old, c->nold, c->oh_new, c->nnew, a, c->obj_new_of_old, c->obj_old_of_new, err)) != SL_OK ||
        (s = match(c->fh_old, c->nfold, c->fh_new, c->nfnew, a, c->fp_new_of_old, c->fp_old_of_new, err)) != SL_OK)
        return s;
    for (uint32_t o = 0; o < c->nold; o++)
        if (c->obj_new_of_old[o] == SL_NONE) {
            c->old_flag[o] = 1;
            st->objects_removed++;
        }
    for (uint32_t i = 0; i < c->nnew; i++)
        if (c->obj_old_of_new[i] == SL_NONE)
            st->objects_added++;
    /* the footprints of both scenes as one list: the new ones, then the old ones without a match */
    uint32_t nf = c->nfnew, nfx = 0;
    for (uint32_t f = 0; f < c->nfold; f++)
        nfx += c->fp_new_of_old[f] == SL_NONE;
    size_t total = (size_t)nf + nfx;
    sl_aabb *box = sl_alloc(a, (total + 1) * sizeof *box);
    uint32_t *src = sl_alloc(a, (total + 1) * sizeof *src); /* < nf: new footprint; else old footprint - nf */
    uint8_t *in = sl_calloc(a, total + 1, 1);
    uint32_t *queue = sl_alloc(a, (total + 1) * sizeof *queue);
    if (!box || !src || !in || !queue) {
        sl_free(a, box, (total + 1) * sizeof *box);
        sl_free(a, src, (total + 1) * sizeof *src);
        sl_free(a, in, total + 1);
        sl_free(a, queue, (total + 1) * sizeof *queue);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    size_t k = 0, nq = 0;
    for (uint32_t f = 0; f < nf; f++, k++) {
        box[k] = footprint_box(c->news, f);
        src[k] = f;
        if (c->fp_old_of_new[f] == SL_NONE)
            in[k] = 1, queue[nq++] = (uint32_t)k;
    }
    for (uint32_t f = 0; f < c->nfold; f++)
        if (c->fp_new_of_old[f] == SL_NONE) {
            box[k] = footprint_box(c->olds, f);
            src[k] = nf + f;
            in[k] = 1, queue[nq++] = (uint32_t)k;
            k++;
        }
    st->footprints_changed = (uint32_t)nq;
    /* every footprint whose box touches one in the zone joins it (a breadth-first closure) */
    for (size_t q = 0; q < nq && close && weaken != 3; q++)
        for (size_t j = 0; j < total; j++)
            if (!in[j] && boxes_touch2d(&box[queue[q]], &box[j], ZONE_TOUCH))
                in[j] = 1, queue[nq++] = (uint32_t)j;
    bool ok = true;
    for (uint32_t f = 0; f < nf; f++)
        c->fp_use[f] = !in[f];
    for (size_t j = 0; j < total && ok; j++) {
        if (!in[j])
            continue;
        c->zone_footprints++;
        ok = zone_add(c, box[j]);
        sl_scene s2 = src[j] < nf ? c->news : c->olds;
        uint32_t f = src[j] < nf ? src[j] : src[j] - nf;
        uint32_t obj = sl_scene_footprint(s2, f).object;
        if (obj != SL_NONE && obj < sl_scene_object_count(s2)) {
            ok = ok && zone_add(c, sl_scene_object_bounds(s2, obj));
            if (src[j] < nf) { /* the old version of a zone object (if it is one) */
                uint32_t o = c->obj_old_of_new[obj];
                if (o != SL_NONE && !c->old_flag[o])
                    c->old_flag[o] = 2;
                uint32_t of = c->fp_old_of_new[f];
                if (of != SL_NONE) { /* its old footprint's object, the same content */
                    uint32_t oo = sl_scene_footprint(c->olds, of).object;
                    if (oo != SL_NONE && oo < c->nold && !c->old_flag[oo])
                        c->old_flag[oo] = 2;
                }
            } else if (!c->old_flag[obj]) {
                c->old_flag[obj] = 2;
            }
        }
    }
    /* the other changed objects (not footprints' objects): their old and new boxes */
    for (uint32_t o = 0; o < c->nold && ok; o++)
        if (c->obj_new_of_old[o] == SL_NONE)
            ok = zone_add(c, sl_scene_object_bounds(c->olds, o));
    for (uint32_t i = 0; i < c->nnew && ok; i++)
        if (c->obj_old_of_new[i] == SL_NONE)
            ok = zone_add(c, sl_scene_object_bounds(c->news, i));
    sl_free(a, box, (total + 1) * sizeof *box);
    sl_free(a, src, (total + 1) * sizeof *src);
    sl_free(a, in, total + 1);
    sl_free(a, queue, (total + 1) * sizeof *queue);
    if (!ok)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    st->zone_footprints = c->zone_footprints;
    st->zone_boxes = (uint32_t)c->zone.count;
    return SL_OK;
}

/* ---- the update ---- */

static const char *const g_methods[] = {"adjustable", "sample"};

sl_status sl_pvs_update(sl_pvs old, sl_scene old_scene, sl_scene new_scene, sl_viewcells cells, const char *output,
                        const sl_pvs_update_options *opt, sl_pvs_update_stats *stats, sl_error *err)
{
    double t0 = sl_now(), c0 = cpu_now();
    sl_pvs_update_stats st;
    memset(&st, 0, sizeof st);
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!old || !old_scene || !new_scene || !cells || !output)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_update: arguments must not be NULL");
    const sl_allocator *a = sl_alloc_or_default(opt ? opt->alloc : NULL);
    uint32_t weaken = opt ? opt->weaken : 0;
    /* the one thread limit (libgomp crashed when asked for 100000 threads) */
    sl_status ts0 = sl_threads_check(opt ? opt->threads : 0, true, "pvs update", err);
    if (ts0 != SL_OK)
        return ts0;
    /* the file must be the old scene's bake, by a method the update knows */
    sl_pvs_info info;
    sl_pvs_get_info(old, &info);
    const char *method = sl_pvs_meta(old, "method"), *options = sl_pvs_meta(old, "options");
    sl_status s = SL_OK;
    if (info.scene_key_version != SL_PVS_SCENE_KEY_VERSION) {
        s = sl_pvs_check_scene(old, old_scene, err); /* an older or newer key format: bake again */
        if (s != SL_OK) {
            sl_error_prefix(err, "pvs update");
            return s;
        }
    }
    const uint64_t old_key = sl_pvs_scene_key(old_scene);
    if (info.object_count != sl_scene_object_count(old_scene) || info.scene_key != old_key)
        /* sl_pvs_check_scene's advice (bake the file again for this scene) would replace a good
         * bake with one of the wrong scene: here the old scene is what was given wrongly */
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "pvs update: the old scene is not the one the file was baked for (the file: %u objects, "
                       "scene key %016llx; the old scene given: %u objects, key %016llx): give as the old scene "
                       "the scene the file was baked for, unedited, or check that the file is the bake you meant "
                       "(no re-bake is needed)",
                       info.object_count, (unsigned long long)info.scene_key, sl_scene_object_count(old_scene),
                       (unsigned long long)old_key);
    bool known = false;
    for (size_t i = 0; method && i < sizeof g_methods / sizeof *g_methods; i++)
        known = known || !strcmp(method, g_methods[i]);
    if (!known)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "pvs update: the file was baked with method %s; an update can re-bake adjustable and sample "
                       "bakes only (their sets depend on the footprints and boxes alone): bake the edited scene "
                       "with pvs build",
                       method ? method : "(none recorded)");
    /* the cells: the full bake of the edited scene would use these; they must be the file's */
    if (sl_viewcells_key(cells) != info.cells_key || sl_viewcells_count(cells) != info.cell_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "pvs update: the edited scene's view cells differ from the file's (%u cells in the file, %u "
                       "now%s): the edit changed the streets or put footprints over them, or the cell options are "
                       "not those of the bake (a bake made with --along is updated with the same --along and --radius); "
                       "every cell's set may change: bake the edited scene with pvs build",
                       info.cell_count, sl_viewcells_count(cells),
                       info.cell_count == sl_viewcells_count(cells) ? ", other shapes" : "");
    static const char *const parts[] = {"the terrain", "the streets", "the BSP", "the mesh occluders"};
    for (int p = 0; p < 4; p++)
        if (hash_fixed(old_scene, p) != hash_fixed(new_scene, p))
            return sl_fail(err, SL_ERROR_UNSUPPORTED,
                           "pvs update: the edit changes %s; an update handles added, removed and moved objects and "
                           "footprints only: bake the edited scene with pvs build",
                           parts[p]);
    update_ctx c;
    memset(&c, 0, sizeof c);
    c.a = a;
    c.olds = old_scene;
    c.news = new_scene;
    c.nold = sl_scene_object_count(old_scene);
    c.nnew = sl_scene_object_count(new_scene);
    c.nfold = sl_scene_footprint_count(old_scene);
    c.nfnew = sl_scene_footprint_count(new_scene);
    st.cells = info.cell_count;
    st.objects_old = c.nold;
    st.objects_new = c.nnew;
    snprintf(st.method, sizeof st.method, "%s", method);
    snprintf(st.options, sizeof st.options, "%s", options ? options : "");
    /* footprints interact only where the method joins them: sample's merged groups (merge=true,
     * eroded as one), adjustable's runs of touching pieces (fuse=true); otherwise each footprint's
     * occluder pieces are its own and the zone needs only the changed ones */
    bool close = options && ((!strcmp(method, "sample") && !strstr(options, "merge=false")) ||
                             (!strcmp(method, "adjustable") && strstr(options, "fuse=true")));
    st.zone_closed = close;
    s = diff_scenes(&c, close, weaken, &st, err);
    uint8_t *affected = NULL;
    uint32_t nc = info.cell_count;
    if (s == SL_OK) {
        affected = sl_calloc(a, (size_t)nc + 1, 1);
        if (!affected)
            s = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
    }
    /* rule (a): the old sets */
    if (s == SL_OK) {
        uint32_t *ids = sl_alloc(a, ((size_t)c.nold + 1) * sizeof *ids);
        if (!ids)
            s = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        for (uint32_t cell = 0; cell < nc && s == SL_OK; cell++) {
            uint32_t n = 0;
            if ((s = sl_pvs_cell_set(old, cell, ids, c.nold, &n, err)) != SL_OK)
                break;
            bool hit = false;
            for (uint32_t k = 0; k < n && !hit && weaken != 1; k++)
                hit = c.old_flag[ids[k]] != 0;
            if (hit) {
                affected[cell] = 1;
                st.cells_by_set++;
            }
        }
        sl_free(a, ids, ((size_t)c.nold + 1) * sizeof *ids);
    }
    /* rule (c): the methods treat footprints above a cell's lowest eye apart, and objects below
     * the highest base at or below it (sl_cell_floor): an edit that changes that base for a cell
     * changes its set wherever the edit is */
    if (s == SL_OK) {
        sl_base_levels bo = {0}, bn = {0};
        if (!sl_base_levels_of_scene(&bo, old_scene, a) || !sl_base_levels_of_scene(&bn, new_scene, a))
            s = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        else if (bo.n != bn.n || memcmp(bo.v, bn.v, (size_t)bo.n * sizeof(double)) != 0) {
            const sl_viewcell *vd = sl_viewcells_data(cells);
            for (uint32_t cell = 0; cell < nc; cell++) {
                double to, tn;
                sl_cell_floor(&bo, &vd[cell], &to);
                sl_cell_floor(&bn, &vd[cell], &tn);
                if (to != tn && !affected[cell]) {
                    affected[cell] = 1;
                    st.cells_by_base++;
                }
            }
        }
        sl_base_levels_free(&bo, a);
        sl_base_levels_free(&bn, a);
    }
    /* rule (b): the probe, on the cells (a) left */
    int threads = opt && opt->threads ? (int)opt->threads : omp_get_max_threads();
    threads = SL_MAX(1, SL_MIN(threads, (int)sl_thread_limit()));
    double tp = sl_now(), tpc = cpu_now();
    if (s == SL_OK && weaken != 2 && c.zone.count) {
        void *probe = NULL;
        /* the probe's options: the file's for adjustable (its coarsest disks); adjustable's defaults
         * for sample (what its prefilter runs) */
        s = sl_adj_probe_create(new_scene, cells, !strcmp(method, "adjustable") ? options : NULL, c.fp_use,
                                c.zone.data, (uint32_t)c.zone.count, a, &probe, err);
        volatile int stop = 0;
        sl_status fs = SL_OK;
        sl_error ferr;
        memset(&ferr, 0, sizeof ferr);
        if (s == SL_OK) {
#pragma omp parallel num_threads(threads)
            {
                void *w = NULL;
                sl_error terr;
                sl_status ts = sl_adj_probe_worker_create(probe, &w, &terr);
#pragma omp for schedule(dynamic, 64)
                for (uint32_t cell = 0; cell < nc; cell++) {
                    if (stop || ts != SL_OK || affected[cell])
                        continue;
                    bool vis = false;
                    ts = sl_adj_probe_cell(w, cell, &vis, &terr);
                    if (ts == SL_OK && vis)
                        affected[cell] = 2;
                }
                if (ts != SL_OK) {
#pragma omp critical(sl_pvs_update)
                    if (!stop) {
                        stop = 1;
                        fs = ts;
                        ferr = terr;
                    }
                }
                if (w)
                    sl_adj_probe_worker_destroy(w);
            }
            if (stop) {
                s = fs;
                if (err)
                    *err = ferr;
            }
        }
        sl_adj_probe_destroy(probe);
        for (uint32_t cell = 0; cell < nc; cell++)
            st.cells_by_probe += affected[cell] == 2;
    }
    st.probe_seconds = sl_now() - tp;
    st.probe_cpu_seconds = cpu_now() - tpc;
    /* the bake: the copied sets stored, the affected cells baked */
    if (s == SL_OK) {
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        bo.method = method;
        bo.method_options = options;
        bo.threads = (uint32_t)threads;
        bo.checkpoint = opt ? opt->checkpoint : NULL;
        bo.alloc = a;
        sl_bake b;
        double tb = sl_now(), tbc = cpu_now();
        s = sl_bake_begin(&b, new_scene, cells, output, &bo, true, err);
        st.prepare_seconds = sl_now() - tb;
        st.prepare_cpu_seconds = cpu_now() - tbc;
        uint32_t *todo = s == SL_OK ? sl_alloc(a, ((size_t)nc + 1) * sizeof *todo) : NULL;
        if (s == SL_OK && !todo)
            s = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        uint32_t nt = 0;
        uint32_t *set = s == SL_OK ? sl_alloc(a, ((size_t)c.nold + 1) * sizeof *set) : NULL;
        uint8_t *enc = s == SL_OK ? sl_alloc(a, ((size_t)c.nold + 1) * 5) : NULL;
        if (s == SL_OK && (!set || !enc))
            s = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        if (s == SL_OK && b.done_count)
            s = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pvs update: %s holds a checkpoint of an earlier bake", b.journal);
        for (uint32_t cell = 0; cell < nc && s == SL_OK; cell++) {
            if (affected[cell]) {
                todo[nt++] = cell;
                continue;
            }
            /* copied: the old set renumbered (sorted when the order changed), in memory only (the
             * journal is for the cells computed here) */
            uint32_t n = 0, m = 0;
            if ((s = sl_pvs_cell_set(old, cell, set, c.nold, &n, err)) != SL_OK)
                break;
            bool sorted = true;
            for (uint32_t k = 0; k < n; k++) {
                uint32_t id = c.obj_new_of_old[set[k]];
                if (id == SL_NONE)
                    continue; /* removed: only with weaken 1 */
                if (m && id < set[m - 1])
                    sorted = false;
                set[m++] = id; /* m <= k: in place */
            }
            if (!sorted)
                for (uint32_t i = 1; i < m; i++) /* nearly sorted: insertion */
                    for (uint32_t j = i; j > 0 && set[j] < set[j - 1]; j--) {
                        uint32_t t = set[j];
                        set[j] = set[j - 1];
                        set[j - 1] = t;
                    }
            uint32_t size = (uint32_t)sl_pvs_encode(set, m, enc);
            s = sl_bake_store_encoded(&b, cell, enc, size, m, 0, false, err);
        }
        sl_free(a, set, ((size_t)c.nold + 1) * sizeof *set);
        sl_free(a, enc, ((size_t)c.nold + 1) * 5);
        st.cells_affected = nt;
        const sl_progress *progress = opt ? &opt->progress : NULL;
        volatile int stop = 0;
        sl_status fs = SL_OK;
        sl_error ferr;
        memset(&ferr, 0, sizeof ferr);
        uint32_t baked = 0;
        double cell_seconds = 0;
        double tr = sl_now(), trc = cpu_now();
        if (s == SL_OK && nt) {
#pragma omp parallel num_threads(threads)
            {
                void *worker = NULL;
                sl_error terr;
                uint32_t *ids = sl_alloc(a, ((size_t)b.object_count + 1) * sizeof(uint32_t));
                sl_status ts = ids ? b.method->worker_create(b.shared, &worker, &terr)
                                   : sl_fail(&terr, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
#pragma omp for schedule(dynamic, 1)
                for (uint32_t i = 0; i < nt; i++) {
                    if (stop || ts != SL_OK)
                        continue;
                    sl_pvs_cell_result res = {ids, 0, 0};
                    double q0 = sl_now();
                    ts = b.method->cell(worker, todo[i], &res, &terr);
                    double secs = sl_now() - q0;
#pragma omp critical(sl_pvs_update)
                    {
                        if (ts == SL_OK && !stop)
                            ts = sl_bake_store(&b, todo[i], ids, res.count, secs, &terr);
                        if (ts == SL_OK && !stop) {
                            baked++;
                            cell_seconds += secs;
                            if (!sl_progress_report(progress, "re-baking cells", baked, nt)) {
                                stop = 2;
                                fs = sl_fail(&ferr, SL_ERROR_CANCELLED, "pvs update: cancelled after %u of %u cells",
                                             baked, nt);
                            }
                        }
                    }
                }
                if (ts != SL_OK) {
#pragma omp critical(sl_pvs_update)
                    if (!stop) {
                        stop = 1;
                        fs = ts;
                        ferr = terr;
                    }
                }
                if (worker)
                    b.method->worker_destroy(worker);
                sl_free(a, ids, ((size_t)b.object_count + 1) * sizeof(uint32_t));
            }
            if (stop) {
                s = fs;
                if (err)
                    *err = ferr;
            }
        }
        st.bake_seconds = sl_now() - tr;
        st.bake_cpu_seconds = cpu_now() - trc;
        st.cell_seconds = cell_seconds;
        /* the motion regions: a kept cell keeps its row too, by the same argument (every sight line
         * from it into the zone is blocked by occluders that did not change) */
        uint8_t *keep = s == SL_OK ? sl_alloc(a, (size_t)nc + 1) : NULL;
        if (s == SL_OK && !keep)
            s = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs update: out of memory");
        if (s == SL_OK) {
            for (uint32_t cell = 0; cell < nc; cell++)
                keep[cell] = !affected[cell];
            b.region_old = old;
            b.region_keep = keep;
            s = sl_bake_finish(&b, output, &bo, err);
            st.regions = b.regions;
            st.region_rows_copied = b.region_copied;
        } else if (b.writer)
            sl_bake_note_kept(&b, err);
        if (todo)
            sl_free(a, todo, ((size_t)nc + 1) * sizeof *todo);
        if (keep)
            sl_free(a, keep, (size_t)nc + 1);
        sl_bake_end(&b);
    }
    sl_free(a, affected, (size_t)nc + 1);
    ctx_free(&c);
    st.seconds = sl_now() - t0;
    st.cpu_seconds = cpu_now() - c0;
    if (stats)
        *stats = st;
    return s;
}

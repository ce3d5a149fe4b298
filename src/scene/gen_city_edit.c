/* Seeded random edits of the buildings in a region of a scene (sl_city_edit, gen.h): the edits
 * `sightline pvs update` is tested and measured on. The scene is copied through the public API
 * with, for every building (an object with a footprint) whose footprint box centre lies in the
 * region, one draw: removed, moved (shifted towards the middle of its row of touching buildings,
 * its height optionally scaled), given a new building inside it, or kept. Same scene and options, same bytes. */
#include "gen_city_internal.h"

sl_city_edit_options sl_city_edit_defaults(void)
{
    sl_city_edit_options o;
    memset(&o, 0, sizeof o);
    o.seed = 1;
    o.remove = 0.25f;
    o.move = 0.25f;
    o.add = 0.2f;
    o.shift = 1.0f;
    o.grow = 1.0f;
    o.tower = 1.0f;
    return o;
}

static sl_status copy_mesh(sl_scene src, sl_scene dst, uint32_t m, sl_error *err)
{
    sl_mesh_view v = sl_scene_mesh(src, m);
    sl_mesh_desc d = {.positions = v.positions, .normals = v.normals, .vertex_count = v.vertex_count,
                      .indices = v.indices, .triangle_count = v.triangle_count, .uvs = v.uvs};
    return sl_scene_add_mesh(dst, &d, NULL, err);
}

/* A prism over polygon xy (n vertices, counter-clockwise) from base to roof: walls and a fan roof. */
static sl_status add_prism(const sl_allocator *a, sl_scene dst, const float *xy, uint32_t n, float base, float roof,
                           uint32_t *mesh, sl_error *err)
{
    size_t nv = 4 * (size_t)n + n + 1, np = nv * 3 * sizeof(float), ni = ((size_t)2 * n + n) * 3 * sizeof(uint32_t);
    float *p = sl_alloc(a, np);
    uint32_t *idx = sl_alloc(a, ni);
    if (!p || !idx) {
        sl_free(a, p, np);
        sl_free(a, idx, ni);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "city edit: out of memory");
    }
    uint32_t v = 0, t = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        float q[4][3] = {{xy[2 * i], xy[2 * i + 1], base}, {xy[2 * j], xy[2 * j + 1], base},
                         {xy[2 * j], xy[2 * j + 1], roof}, {xy[2 * i], xy[2 * i + 1], roof}};
        memcpy(p + 3 * v, q, sizeof q);
        uint32_t tri[6] = {v, v + 1, v + 2, v, v + 2, v + 3};
        memcpy(idx + 3 * t, tri, sizeof tri);
        v += 4, t += 2;
    }
    double cx = 0, cy = 0;
    for (uint32_t i = 0; i < n; i++)
        cx += xy[2 * i], cy += xy[2 * i + 1];
    uint32_t c = v;
    p[3 * v] = (float)(cx / n), p[3 * v + 1] = (float)(cy / n), p[3 * v + 2] = roof;
    v++;
    for (uint32_t i = 0; i < n; i++) {
        p[3 * v] = xy[2 * i], p[3 * v + 1] = xy[2 * i + 1], p[3 * v + 2] = roof;
        v++;
    }
    for (uint32_t i = 0; i < n; i++) {
        uint32_t tri[3] = {c, c + 1 + i, c + 1 + (i + 1) % n};
        memcpy(idx + 3 * t, tri, sizeof tri);
        t++;
    }
    sl_mesh_desc d = {.positions = p, .vertex_count = v, .indices = idx, .triangle_count = t};
    sl_status st = sl_scene_add_mesh(dst, &d, mesh, err);
    sl_free(a, p, np);
    sl_free(a, idx, ni);
    return st;
}

/* The centre of the box of footprint f's group (footprints whose boxes touch, transitively);
 * returns the group's size. box: 4 floats per footprint; q, in: scratch (in is left zeroed). */
static uint32_t group_centre(sl_scene scene, uint32_t f, const float *box, uint32_t *q, uint8_t *in, float *cx,
                             float *cy)
{
    const uint32_t nf = sl_scene_footprint_count(scene);
    const float tol = 0.05f;
    uint32_t n = 0;
    q[n++] = f;
    in[f] = 1;
    float g[4] = {box[4 * f], box[4 * f + 1], box[4 * f + 2], box[4 * f + 3]};
    for (uint32_t k = 0; k < n; k++) {
        const float *a = box + 4 * (size_t)q[k];
        for (uint32_t j = 0; j < nf; j++) {
            const float *b = box + 4 * (size_t)j;
            if (!in[j] && a[0] <= b[2] + tol && b[0] <= a[2] + tol && a[1] <= b[3] + tol && b[1] <= a[3] + tol) {
                in[j] = 1;
                q[n++] = j;
                g[0] = fminf(g[0], b[0]), g[1] = fminf(g[1], b[1]), g[2] = fmaxf(g[2], b[2]), g[3] = fmaxf(g[3], b[3]);
            }
        }
    }
    for (uint32_t k = 0; k < n; k++)
        in[q[k]] = 0;
    *cx = 0.5f * (g[0] + g[2]), *cy = 0.5f * (g[1] + g[3]);
    return n;
}

sl_status sl_city_edit(sl_scene scene, const sl_city_edit_options *opt, const sl_allocator *alloc, sl_scene *out,
                       sl_city_edit_stats *stats, sl_error *err)
{
    if (out)
        *out = NULL;
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!scene || !opt || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_city_edit: scene, opt and out must not be NULL");
    if (!(opt->remove >= 0 && opt->move >= 0 && opt->add >= 0 && opt->remove + opt->move + opt->add <= 1.0f + 1e-6f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "city edit: remove, move and add are probabilities in [0, 1] with a sum of at most 1");
    if (!(opt->shift >= 0 && opt->shift <= 100) || !(opt->region[0] <= opt->region[2]) ||
        !(opt->region[1] <= opt->region[3]))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city edit: shift must be 0..100 m and the region X0,Y0,X1,Y1 "
                                                       "with X0 <= X1 and Y0 <= Y1");
    if (!(opt->grow >= 1 && opt->grow <= 10) || !(opt->tower >= 0.1f && opt->tower <= 10))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city edit: grow must be 1..10 and tower 0.1..10");
    sl_bsp_view bv;
    if (sl_scene_bsp(scene, &bv) || sl_scene_occluder_count(scene) > 0)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "city edit: the scene has BSP data or mesh occluders; only 2.5D "
                                                  "scenes (footprints) are edited");
    const uint32_t no = sl_scene_object_count(scene), nf = sl_scene_footprint_count(scene);
    /* per object: its footprint (buildings), the draw */
    const sl_allocator *a = sl_alloc_or_default(alloc);
    const size_t no1 = (size_t)no + 1, nf1 = (size_t)nf + 1;
    uint32_t *fp_of = sl_alloc(a, no1 * sizeof *fp_of);
    uint8_t *what = sl_calloc(a, no1, 1); /* 0 keep, 1 remove, 2 move, 3 new building */
    uint32_t *new_id = sl_alloc(a, no1 * sizeof *new_id);
    float *shift = sl_calloc(a, 3 * no1, sizeof *shift); /* dx, dy, height scale */
    float *box = sl_alloc(a, nf1 * 4 * sizeof *box);
    uint32_t *gq = sl_alloc(a, nf1 * sizeof *gq);
    uint8_t *gin = sl_calloc(a, nf1, 1);
#define EDIT_FREE()                                                                                                    \
    do {                                                                                                               \
        sl_free(a, fp_of, no1 * sizeof *fp_of), sl_free(a, what, no1), sl_free(a, new_id, no1 * sizeof *new_id);      \
        sl_free(a, shift, 3 * no1 * sizeof *shift), sl_free(a, box, nf1 * 4 * sizeof *box);                           \
        sl_free(a, gq, nf1 * sizeof *gq), sl_free(a, gin, nf1);                                                        \
    } while (0)
    if (!fp_of || !what || !new_id || !shift || !box || !gq || !gin) {
        EDIT_FREE();
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "city edit: out of memory");
    }
    for (uint32_t o = 0; o < no; o++)
        fp_of[o] = SL_NONE;
    for (uint32_t f = 0; f < nf; f++) {
        sl_footprint_view v = sl_scene_footprint(scene, f);
        if (v.object < no && fp_of[v.object] == SL_NONE)
            fp_of[v.object] = f;
    }
    const float rcx = 0.5f * (opt->region[0] + opt->region[2]), rcy = 0.5f * (opt->region[1] + opt->region[3]);
    for (uint32_t f = 0; f < nf; f++) {
        sl_footprint_view v = sl_scene_footprint(scene, f);
        float *b = box + 4 * (size_t)f;
        b[0] = b[1] = INFINITY, b[2] = b[3] = -INFINITY;
        for (uint32_t i = 0; i < v.vertex_count; i++) {
            b[0] = fminf(b[0], v.xy[2 * i]), b[2] = fmaxf(b[2], v.xy[2 * i]);
            b[1] = fminf(b[1], v.xy[2 * i + 1]), b[3] = fmaxf(b[3], v.xy[2 * i + 1]);
        }
    }
    sl_rng rng;
    sl_rng_seed(&rng, opt->seed, 0x45444954u);
    for (uint32_t o = 0; o < no; o++) {
        if (fp_of[o] == SL_NONE)
            continue;
        sl_footprint_view v = sl_scene_footprint(scene, fp_of[o]);
        float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
        for (uint32_t i = 0; i < v.vertex_count; i++) {
            x0 = fminf(x0, v.xy[2 * i]), x1 = fmaxf(x1, v.xy[2 * i]);
            y0 = fminf(y0, v.xy[2 * i + 1]), y1 = fmaxf(y1, v.xy[2 * i + 1]);
        }
        float cx = 0.5f * (x0 + x1), cy = 0.5f * (y0 + y1);
        if (cx < opt->region[0] || cx > opt->region[2] || cy < opt->region[1] || cy > opt->region[3])
            continue;
        float u = sl_rng_float(&rng);
        float d = sl_rng_range(&rng, 0, opt->shift), s = sl_rng_range(&rng, 1.0f, opt->grow);
        if (u < opt->remove) {
            what[o] = 1;
        } else if (u < opt->remove + opt->move) {
            what[o] = 2;
            /* towards the middle of its row of touching buildings (a perimeter block's courtyard),
             * away from the street; a building standing alone moves towards the region's centre */
            float gx = rcx, gy = rcy;
            if (group_centre(scene, fp_of[o], box, gq, gin, &gx, &gy) > 1) {
                /* the group's centre */
            } else {
                gx = rcx, gy = rcy;
            }
            float dx = gx - cx, dy = gy - cy, l = sqrtf(dx * dx + dy * dy);
            shift[3 * o] = l > 1e-3f ? d * dx / l : 0;
            shift[3 * o + 1] = l > 1e-3f ? d * dy / l : 0;
            shift[3 * o + 2] = s;
        } else if (u < opt->remove + opt->move + opt->add) {
            what[o] = 3;
        }
    }
    sl_scene dst = NULL;
    sl_status st = sl_scene_create(alloc, &dst, err);
    for (uint32_t m = 0; st == SL_OK && m < sl_scene_mesh_count(scene); m++)
        st = copy_mesh(scene, dst, m, err);
    for (uint32_t k = 1; st == SL_OK && k <= sl_scene_material_count(scene); k++) {
        sl_material mat;
        if (sl_scene_material(scene, k, &mat))
            st = sl_scene_add_material(dst, &mat, NULL, err);
    }
    for (uint32_t o = 0; st == SL_OK && o < no; o++) {
        new_id[o] = SL_NONE;
        if (what[o] == 1) {
            if (stats)
                stats->removed++;
            continue;
        }
        sl_object_view v = sl_scene_object(scene, o);
        sl_affine t = v.transform;
        if (what[o] == 2) {
            sl_footprint_view f = sl_scene_footprint(scene, fp_of[o]);
            float sc = shift[3 * o + 2], base = f.base_z;
            for (int c = 0; c < 4; c++)
                t.m[8 + c] *= sc;
            t.m[11] += base * (1 - sc);
            t.m[3] += shift[3 * o], t.m[7] += shift[3 * o + 1];
            if (stats)
                stats->moved++;
        }
        sl_object_desc d = {.mesh = v.mesh, .transform = &t, .color = v.color, .kind = v.kind, .flags = v.flags,
                            .material = v.material};
        st = sl_scene_add_object(dst, &d, &new_id[o], err);
        const char *name = sl_scene_object_name(scene, o);
        if (st == SL_OK && name && name[0])
            st = sl_scene_set_object_name(dst, new_id[o], name, err);
        /* an untouched object keeps its motion record (the cars: docs/motion.md) */
        sl_object_motion m;
        if (st == SL_OK && what[o] == 0 && sl_scene_object_motion(scene, o, &m))
            st = sl_scene_set_object_motion(dst, new_id[o], &m, err);
    }
    for (uint32_t f = 0; st == SL_OK && f < nf; f++) {
        sl_footprint_view v = sl_scene_footprint(scene, f);
        uint32_t o = v.object;
        if (o < no && what[o] == 1)
            continue;
        const size_t nxy = ((size_t)v.vertex_count + 1) * 2 * sizeof(float);
        float *xy = sl_alloc(a, nxy);
        if (!xy) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "city edit: out of memory");
            break;
        }
        memcpy(xy, v.xy, (size_t)v.vertex_count * 2 * sizeof(float));
        float roof = v.roof_z;
        if (o < no && what[o] == 2) {
            for (uint32_t i = 0; i < v.vertex_count; i++)
                xy[2 * i] += shift[3 * o], xy[2 * i + 1] += shift[3 * o + 1];
            roof = v.base_z + (v.roof_z - v.base_z) * shift[3 * o + 2];
        }
        sl_footprint_desc d = {.xy = xy, .vertex_count = v.vertex_count, .base_z = v.base_z, .roof_z = roof,
                               .object = o < no ? new_id[o] : SL_NONE};
        st = sl_scene_add_footprint(dst, &d, NULL, err);
        sl_free(a, xy, nxy);
    }
    /* the towers: inside their buildings (the footprint halved about its vertex centroid, which
     * stays within the footprint's box), twice as high, appended */
    for (uint32_t o = 0; st == SL_OK && o < no; o++) {
        if (what[o] != 3)
            continue;
        sl_footprint_view v = sl_scene_footprint(scene, fp_of[o]);
        const size_t nxy = ((size_t)v.vertex_count + 1) * 2 * sizeof(float);
        float *xy = sl_alloc(a, nxy);
        if (!xy) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "city edit: out of memory");
            break;
        }
        double cx = 0, cy = 0;
        for (uint32_t i = 0; i < v.vertex_count; i++)
            cx += v.xy[2 * i], cy += v.xy[2 * i + 1];
        cx /= v.vertex_count, cy /= v.vertex_count;
        for (uint32_t i = 0; i < v.vertex_count; i++) {
            xy[2 * i] = (float)(cx + 0.5 * (v.xy[2 * i] - cx));
            xy[2 * i + 1] = (float)(cy + 0.5 * (v.xy[2 * i + 1] - cy));
        }
        float roof = v.base_z + opt->tower * (v.roof_z - v.base_z);
        uint32_t mesh = SL_NONE, id = SL_NONE;
        st = add_prism(a, dst, xy, v.vertex_count, v.base_z, roof, &mesh, err);
        sl_object_view ov = sl_scene_object(scene, o);
        sl_object_desc d = {.mesh = mesh, .color = ov.color, .kind = ov.kind, .flags = ov.flags};
        if (st == SL_OK)
            st = sl_scene_add_object(dst, &d, &id, err);
        sl_footprint_desc fd = {.xy = xy, .vertex_count = v.vertex_count, .base_z = v.base_z, .roof_z = roof,
                                .object = id};
        if (st == SL_OK)
            st = sl_scene_add_footprint(dst, &fd, NULL, err);
        sl_free(a, xy, nxy);
        if (stats && st == SL_OK)
            stats->added++;
    }
    sl_terrain_view tv;
    if (st == SL_OK && sl_scene_terrain(scene, &tv))
        st = sl_scene_set_terrain(dst, &tv, err);
    for (uint32_t i = 0; st == SL_OK && i < sl_scene_street_polygon_count(scene); i++) {
        sl_polygon_view p = sl_scene_street_polygon(scene, i);
        st = sl_scene_add_street_polygon(dst, p.xy, p.vertex_count, err);
    }
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nnode, nedge;
    sl_scene_street_graph(scene, &nodes, &nnode, &edges, &nedge);
    if (st == SL_OK && (nnode || nedge))
        st = sl_scene_set_street_graph(dst, nodes, nnode, edges, nedge, err);
    for (uint32_t i = 0; st == SL_OK && i < sl_scene_meta_count(scene); i++) {
        const char *k, *v;
        sl_scene_meta_at(scene, i, &k, &v);
        st = sl_scene_set_meta(dst, k, v, err);
    }
    if (st == SL_OK && sl_scene_base_dir(scene))
        st = sl_scene_set_base_dir(dst, sl_scene_base_dir(scene), err);
    EDIT_FREE();
#undef EDIT_FREE
    if (st != SL_OK) {
        sl_scene_destroy(dst);
        return st;
    }
    *out = dst;
    return SL_OK;
}

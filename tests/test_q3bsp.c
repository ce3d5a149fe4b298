/* The Quake III map importer: a tiny map built here byte by byte (exact counts, objects, PVS
 * bits, leaf lookups, metadata), node renumbering, hostile variants of it and of real maps,
 * .pk3 access, and every map shipped in OpenArena's pak1-maps.pk3 when it is installed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <glob.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zip.h>

#include "core/sl_core.h"
#include "import/pk3.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/region.h"
#include "support/counting_alloc.h"
#include "support/pk3_names.h"

#define OA_PK3 SL_TEST_OA_PK3

/* ---- a small IBSP 46 writer ---- */

enum { L_ENT, L_SHD, L_PLN, L_NOD, L_LEF, L_LFF, L_LFB, L_MOD, L_BRU, L_BRS, L_VRT, L_MSV, L_EFF, L_FAC, L_LMP, L_LVL,
       L_VIS, L_COUNT };

typedef struct bspw {
    uint8_t *lump[L_COUNT];
    size_t len[L_COUNT];
} bspw;

static void put(bspw *w, int lump, const void *p, size_t n)
{
    w->lump[lump] = realloc(w->lump[lump], w->len[lump] + n);
    assert_non_null(w->lump[lump]);
    memcpy(w->lump[lump] + w->len[lump], p, n);
    w->len[lump] += n;
}
static void put_i(bspw *w, int lump, int32_t v) { put(w, lump, &v, 4); } /* the test host is little-endian */
static void put_f(bspw *w, int lump, float v) { put(w, lump, &v, 4); }

static void shader(bspw *w, const char *name, int32_t flags, int32_t contents)
{
    char buf[64] = {0};
    strncpy(buf, name, sizeof buf - 1);
    put(w, L_SHD, buf, 64);
    put_i(w, L_SHD, flags);
    put_i(w, L_SHD, contents);
}
static void plane(bspw *w, float nx, float ny, float nz, float dist)
{
    put_f(w, L_PLN, nx), put_f(w, L_PLN, ny), put_f(w, L_PLN, nz), put_f(w, L_PLN, dist);
}
static void node(bspw *w, int32_t pl, int32_t front, int32_t back)
{
    int32_t v[9] = {pl, front, back, -128, -128, -128, 128, 128, 128};
    put(w, L_NOD, v, sizeof v);
}
static void leaf(bspw *w, int32_t cluster, int32_t x0, int32_t x1, int32_t ff, int32_t nf, int32_t fb, int32_t nb)
{
    int32_t v[12] = {cluster, 0, x0, -128, -128, x1, 128, 128, ff, nf, fb, nb};
    put(w, L_LEF, v, sizeof v);
}
static void vert(bspw *w, float x, float y, float z, float nx, float ny, float nz)
{
    float v[10] = {x, y, z, 0, 0, 0, 0, nx, ny, nz};
    put(w, L_VRT, v, sizeof v);
    uint8_t rgba[4] = {255, 255, 255, 255};
    put(w, L_VRT, rgba, 4);
}
static void face(bspw *w, int32_t sh, int32_t type, int32_t v0, int32_t nv, int32_t m0, int32_t nm, int32_t pw, int32_t ph)
{
    int32_t head[12] = {sh, -1, type, v0, nv, m0, nm, -1, 0, 0, 0, 0};
    float f[12] = {0};
    f[11] = 1; /* face normal +z (only a fallback) */
    int32_t size[2] = {pw, ph};
    put(w, L_FAC, head, sizeof head);
    put(w, L_FAC, f, sizeof f);
    put(w, L_FAC, size, sizeof size);
}

/* Concatenate header and lumps; *size receives the byte count. */
static uint8_t *bspw_finish(bspw *w, size_t *size)
{
    size_t off = 8 + 8 * L_COUNT, total = off;
    for (int k = 0; k < L_COUNT; k++)
        total += (w->len[k] + 3) & ~(size_t)3;
    uint8_t *out = calloc(1, total);
    assert_non_null(out);
    memcpy(out, "IBSP", 4);
    int32_t version = 46;
    memcpy(out + 4, &version, 4);
    for (int k = 0; k < L_COUNT; k++) {
        int32_t o = (int32_t)off, l = (int32_t)w->len[k];
        memcpy(out + 8 + 8 * k, &o, 4);
        memcpy(out + 12 + 8 * k, &l, 4);
        if (w->len[k])
            memcpy(out + off, w->lump[k], w->len[k]);
        off += (w->len[k] + 3) & ~(size_t)3;
        free(w->lump[k]);
    }
    *size = total;
    return out;
}

/* The tiny map. Units; x >= 0 is leaf 0 (cluster 0), x < 0 leaf 1 (cluster 1).
 *  face 0: polygon, wall shader, floor quad in leaf 0       -> object 0 (occluder)
 *  face 1: 3x3 patch, wall shader, bump in leaf 1           -> object 3 (occluder)
 *  face 2: mesh (one triangle), wall shader, leaf 1         -> object 4 (mesh: not an occluder)
 *  face 3: billboard in leaf 1                              -> nothing
 *  face 4: polygon, sky shader, leaf 0                      -> object 1 (sky)
 *  face 5: polygon, water shader, leaves 0 and 1            -> object 2 (owned by leaf 0)
 *  face 6: polygon, wall shader, in no leaf                 -> object 5 (world left-overs, occluder)
 *  face 7: polygon, wall shader, brush model 1 (a door)     -> object 6 (not an occluder)
 * with_vis: 2 clusters, rows of 1 byte: cluster 0 sees {0}, cluster 1 sees {0, 1}.
 * model_leaf: a third leaf that no node reaches, cluster field 0, referencing face 7 (the door),
 * as q3map writes one for every brush model. */
static uint8_t *tiny_map_ents(size_t *size, bool with_vis, bool model_leaf, const char *ents)
{
    bspw w = {0};
    if (!ents)
        ents = "{\n\"classname\" \"worldspawn\"\n\"message\" \"Tiny test map\"\n\"_farplanedist\" \"1024\"\n}\n"
               "{\n\"classname\" \"info_player_deathmatch\"\n\"origin\" \"32 0 16\"\n}\n"
               "{\n\"origin\" \"-64 0 16\"\n\"classname\" \"info_player_start\"\n}\n"
               "{\n\"classname\" \"func_door\"\n\"model\" \"*1\"\n}\n";
    put(&w, L_ENT, ents, strlen(ents) + 1);
    shader(&w, "textures/test/wall", 0, 1);
    shader(&w, "textures/skies/tiny_sky", 0x4, 1);
    shader(&w, "textures/liquids/water", 0, 32);
    plane(&w, 1, 0, 0, 0);
    plane(&w, 0, 0, 1, 0);
    node(&w, 0, -1, -2);
    leaf(&w, 0, 0, 128, 0, 3, 0, 0);
    leaf(&w, 1, -128, 0, 3, 4, 0, 1);
    if (model_leaf)
        leaf(&w, 0, -512, -256, 7, 1, 0, 0);
    int32_t lf[] = {0, 4, 5, 1, 2, 3, 5, 7};
    for (size_t i = 0; i < SL_COUNTOF(lf) - !model_leaf; i++)
        put_i(&w, L_LFF, lf[i]);
    put_i(&w, L_LFB, 0);
    int32_t brush[3] = {0, 1, 0}, side[2] = {1, 0};
    put(&w, L_BRU, brush, sizeof brush);
    put(&w, L_BRS, side, sizeof side);
    float box[6] = {-128, -128, -128, 128, 128, 128};
    int32_t m0[4] = {0, 7, 0, 1}, m1[4] = {7, 1, 1, 0};
    put(&w, L_MOD, box, sizeof box), put(&w, L_MOD, m0, sizeof m0);
    put(&w, L_MOD, box, sizeof box), put(&w, L_MOD, m1, sizeof m1);
    /* face 0: vertices 0-3, meshverts 0-5, clockwise from above as Quake III writes them */
    vert(&w, 16, -16, -32, 0, 0, 1), vert(&w, 48, -16, -32, 0, 0, 1), vert(&w, 48, 16, -32, 0, 0, 1);
    vert(&w, 16, 16, -32, 0, 0, 1);
    int32_t quad[6] = {0, 2, 1, 0, 3, 2};
    for (int i = 0; i < 6; i++)
        put_i(&w, L_MSV, quad[i]);
    face(&w, 0, 1, 0, 4, 0, 6, 0, 0);
    /* face 1: vertices 4-12, a 3x3 patch over x in [-96,-32], y in [-32,32], centre raised to 32 */
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++)
            vert(&w, -96 + 32.0f * i, -32 + 32.0f * j, i == 1 && j == 1 ? 32 : 0, 0, 0, 1);
    face(&w, 0, 2, 4, 9, 0, 0, 3, 3);
    /* face 2: vertices 13-15, meshverts 6-8 */
    vert(&w, -100, 40, 0, 0, 0, 1), vert(&w, -90, 40, 0, 0, 0, 1), vert(&w, -95, 50, 0, 0, 0, 1);
    put_i(&w, L_MSV, 0), put_i(&w, L_MSV, 2), put_i(&w, L_MSV, 1);
    face(&w, 0, 3, 13, 3, 6, 3, 0, 0);
    /* face 3: a flare */
    face(&w, 0, 4, 0, 0, 0, 0, 0, 0);
    /* face 4: vertices 16-18 facing down, meshverts 9-11 */
    vert(&w, 16, 0, 60, 0, 0, -1), vert(&w, 48, 0, 60, 0, 0, -1), vert(&w, 32, 16, 60, 0, 0, -1);
    put_i(&w, L_MSV, 0), put_i(&w, L_MSV, 1), put_i(&w, L_MSV, 2);
    face(&w, 1, 1, 16, 3, 9, 3, 0, 0);
    /* face 5: vertices 19-22 (water quad across x = 0), meshverts 12-17 */
    vert(&w, -16, -16, -40, 0, 0, 1), vert(&w, 16, -16, -40, 0, 0, 1), vert(&w, 16, 16, -40, 0, 0, 1);
    vert(&w, -16, 16, -40, 0, 0, 1);
    for (int i = 0; i < 6; i++)
        put_i(&w, L_MSV, quad[i]);
    face(&w, 2, 1, 19, 4, 12, 6, 0, 0);
    /* faces 6 and 7: one triangle each, vertices 23-25 and 26-28, meshverts 18-20 and 21-23 */
    vert(&w, 100, 100, 0, 0, 0, 1), vert(&w, 110, 100, 0, 0, 0, 1), vert(&w, 105, 110, 0, 0, 0, 1);
    put_i(&w, L_MSV, 0), put_i(&w, L_MSV, 2), put_i(&w, L_MSV, 1);
    face(&w, 0, 1, 23, 3, 18, 3, 0, 0);
    vert(&w, 0, 100, 0, 0, 0, 1), vert(&w, 10, 100, 0, 0, 0, 1), vert(&w, 5, 110, 0, 0, 0, 1);
    put_i(&w, L_MSV, 0), put_i(&w, L_MSV, 2), put_i(&w, L_MSV, 1);
    face(&w, 0, 1, 26, 3, 21, 3, 0, 0);
    if (with_vis) {
        put_i(&w, L_VIS, 2), put_i(&w, L_VIS, 1);
        uint8_t rows[2] = {0x01, 0x03};
        put(&w, L_VIS, rows, 2);
    }
    return bspw_finish(&w, size);
}

static uint8_t *tiny_map_ex(size_t *size, bool with_vis, bool model_leaf)
{
    return tiny_map_ents(size, with_vis, model_leaf, NULL);
}

static uint8_t *tiny_map(size_t *size, bool with_vis) { return tiny_map_ex(size, with_vis, false); }

/* Byte offset of record i of lump k in a map. */
static size_t lump_at(const uint8_t *map, int k, size_t rec, size_t i)
{
    int32_t off;
    memcpy(&off, map + 8 + 8 * k, 4);
    return (size_t)off + rec * i;
}
static void poke_i(uint8_t *map, size_t at, int32_t v) { memcpy(map + at, &v, 4); }
static void poke_f(uint8_t *map, size_t at, float v) { memcpy(map + at, &v, 4); }

static bool contains(const char *s, const char *part) { return s && strstr(s, part) != NULL; }

/* ---- the tiny map ---- */

static bool stop_now(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)user, (void)stage, (void)done, (void)total;
    return false;
}

static void test_tiny_map(void **state)
{
    (void)state;
    size_t size;
    uint8_t *map = tiny_map(&size, true);
    sl_test_counter counter = {0};
    sl_allocator a = sl_test_counting_allocator(&counter);
    sl_scene s;
    sl_error err;
    sl_status st = sl_import_q3bsp_memory(map, size, "maps/tiny.bsp", NULL, &a, &s, &err);
    if (st != SL_OK)
        fail_msg("%s", err.message);

    sl_scene_stats stats;
    sl_scene_get_stats(s, &stats);
    assert_int_equal(stats.object_count, 7);
    assert_int_equal(stats.objects_per_kind[SL_KIND_BSP_FACES], 7);
    assert_int_equal(stats.triangle_count, 8 + 2 * 8 * 8); /* 2+1+2+1+1+1 flat + 128 for the patch */
    /* per object: triangles, vertices, occluder flag */
    const uint32_t tris[7] = {2, 1, 2, 128, 1, 1, 1}, verts[7] = {4, 3, 4, 81, 3, 3, 3};
    const bool occluder[7] = {true, false, false, true, false, true, false};
    for (uint32_t o = 0; o < 7; o++) {
        sl_object_view ov = sl_scene_object(s, o);
        sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
        assert_int_equal(ov.kind, SL_KIND_BSP_FACES);
        assert_int_equal(mv.triangle_count, tris[o]);
        assert_int_equal(mv.vertex_count, verts[o]);
        assert_int_equal((ov.flags & SL_OBJECT_OCCLUDER) != 0, occluder[o]);
        assert_int_equal(ov.color & 0xff, 0xff);
        /* every triangle is counter-clockwise seen from the side its vertex normals point to */
        for (uint32_t t = 0; t < mv.triangle_count; t++) {
            const uint32_t *ix = mv.indices + 3 * t;
            const float *p0 = mv.positions + 3 * ix[0], *p1 = mv.positions + 3 * ix[1], *p2 = mv.positions + 3 * ix[2];
            float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]}, e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
            float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            const float *vn = mv.normals + 3 * ix[0];
            assert_true(n[0] * vn[0] + n[1] * vn[1] + n[2] * vn[2] > 0);
        }
    }
    /* same shader, same colour; different shaders here hash apart */
    assert_int_equal(sl_scene_object(s, 0).color, sl_scene_object(s, 3).color);
    assert_int_not_equal(sl_scene_object(s, 0).color, sl_scene_object(s, 1).color);
    /* metres: the floor quad (16..48 units) spans 0.5..1.5 m at z = -1 m */
    sl_aabb b0 = sl_scene_object_bounds(s, 0);
    assert_float_equal(b0.min.x, 0.5f, 1e-6f);
    assert_float_equal(b0.max.x, 1.5f, 1e-6f);
    assert_float_equal(b0.min.z, -1.0f, 1e-6f);
    /* the patch centre: Bezier weight 1/4 on the raised control point (32 units) -> 8 units */
    sl_mesh_view patch = sl_scene_mesh(s, sl_scene_object(s, 3).mesh);
    const float *centre = patch.positions + 3 * (4 * 9 + 4);
    assert_float_equal(centre[0], -2.0f, 1e-6f);
    assert_float_equal(centre[1], 0.0f, 1e-6f);
    assert_float_equal(centre[2], 0.25f, 1e-6f);

    sl_bsp_view bsp;
    assert_true(sl_scene_bsp(s, &bsp));
    assert_int_equal(bsp.plane_count, 2);
    assert_int_equal(bsp.node_count, 1);
    assert_int_equal(bsp.leaf_count, 2);
    assert_int_equal(bsp.cluster_count, 2);
    assert_int_equal(bsp.cluster_bytes, 1);
    assert_non_null(bsp.pvs);
    assert_int_equal(bsp.pvs[0], 0x01);
    assert_int_equal(bsp.pvs[1], 0x03);
    assert_float_equal(bsp.planes[0].a, 1.0f, 0);
    assert_float_equal(bsp.planes[0].d, 0.0f, 0);
    assert_float_equal(bsp.nodes[0].bounds.max.x, 4.0f, 0);
    assert_int_equal(bsp.nodes[0].children[0], -1);
    assert_int_equal(bsp.nodes[0].children[1], -2);
    assert_int_equal(bsp.leaves[0].cluster, 0);
    assert_int_equal(bsp.leaves[1].cluster, 1);
    assert_float_equal(bsp.leaves[1].bounds.min.x, -4.0f, 0);
    /* leaf 0 references faces 0, 4, 5; leaf 1 faces 1, 2, 3 (no geometry), 5 */
    assert_int_equal(bsp.leaves[0].object_count, 3);
    assert_int_equal(bsp.leaves[1].object_count, 3);
    const uint32_t lo0[3] = {0, 1, 2}, lo1[3] = {2, 3, 4};
    for (int i = 0; i < 3; i++) {
        assert_int_equal(bsp.leaf_objects[bsp.leaves[0].first_object + i], lo0[i]);
        assert_int_equal(bsp.leaf_objects[bsp.leaves[1].first_object + i], lo1[i]);
    }
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){1, 0, 0.5f}), 0);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){-2, 0, 0.5f}), 1);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){0, 0, 0}), 0); /* on the plane: front */

    assert_string_equal(sl_scene_meta(s, "q3.map"), "tiny");
    /* the base name and a content hash, not the path as given (issue 12) */
    assert_string_equal(sl_scene_meta(s, "source"), "tiny.bsp");
    char hex[17];
    snprintf(hex, sizeof hex, "%016llx", (unsigned long long)sl_hash64(map, size, 0));
    assert_string_equal(sl_scene_meta(s, "source.xxh3"), hex);
    assert_string_equal(sl_scene_meta(s, "q3.spawns"), "1.0000 0.0000 0.5000;-2.0000 0.0000 0.5000");
    assert_string_equal(sl_scene_meta(s, "q3.spawn_count"), "2");
    assert_string_equal(sl_scene_meta(s, "q3.sky_objects"), "1");
    assert_string_equal(sl_scene_meta(s, "q3.title"), "Tiny test map");
    assert_string_equal(sl_scene_meta(s, "q3.farplanedist"), "32.0000"); /* 1024 units */
    assert_string_equal(sl_scene_meta(s, "q3.entities"), "4");
    assert_string_equal(sl_scene_meta(s, "q3.patches"), "1");
    assert_string_equal(sl_scene_meta(s, "q3.clusters"), "2");
    assert_string_equal(sl_scene_meta(s, "q3.has_vis"), "yes");
    assert_string_equal(sl_scene_meta(s, "q3.occluder_objects"), "3");
    sl_scene_destroy(s);
    assert_int_equal(counter.live, 0);

    /* options: bezier level 2, unit scale 1, one triangle per object */
    sl_import_options opt = sl_import_defaults();
    opt.bezier_level = 2;
    opt.unit_scale = 1;
    opt.split_triangles = 1;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "tiny", &opt, &a, &s, &err), SL_OK);
    sl_scene_get_stats(s, &stats);
    assert_int_equal(stats.triangle_count, 8 + 2 * 2 * 2);
    /* objects of one face stay whole: the two-triangle faces and the 8-triangle patch */
    assert_int_equal(stats.object_count, 7);
    assert_float_equal(sl_scene_object_bounds(s, 0).max.x, 48.0f, 0);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){32, 0, 16}), 0);
    sl_scene_destroy(s);

    /* a progress callback that says stop */
    opt = sl_import_defaults();
    opt.progress.fn = stop_now;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "tiny", &opt, &a, &s, &err), SL_ERROR_CANCELLED);
    assert_null(s);
    assert_int_equal(counter.live, 0);

    opt = sl_import_defaults();
    opt.unit_scale = -1;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "tiny", &opt, &a, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    opt.unit_scale = 0;
    opt.bezier_level = 1000;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "tiny", &opt, &a, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(s);
    assert_int_equal(counter.live, 0);
    free(map);

    /* without vis data: clusters from the leaves, no PVS */
    map = tiny_map(&size, false);
    assert_int_equal(sl_import_q3bsp_memory(map, size, "tiny", NULL, &a, &s, &err), SL_OK);
    assert_true(sl_scene_bsp(s, &bsp));
    assert_int_equal(bsp.cluster_count, 2);
    assert_null(bsp.pvs);
    assert_string_equal(sl_scene_meta(s, "q3.has_vis"), "no");
    sl_scene_destroy(s);
    assert_int_equal(counter.live, 0);
    free(map);
}

/* Nodes out of pre-order are renumbered so that children follow parents; a cycle is an error. */
/* A leaf the world's tree does not reach (q3map writes one per brush model, cluster field 0) is
 * in no cluster and lists no object: the door is in no leaf (always drawn), the map's PVS does not
 * tie it to cluster 0, and cluster 0's view cell does not grow to the model's leaf box. */
static void test_model_leaf(void **state)
{
    (void)state;
    size_t size;
    uint8_t *map = tiny_map_ex(&size, true, true);
    sl_scene s;
    sl_error err;
    sl_status st = sl_import_q3bsp_memory(map, size, "maps/tiny.bsp", NULL, NULL, &s, &err);
    if (st != SL_OK)
        fail_msg("%s", err.message);
    sl_bsp_view b;
    assert_true(sl_scene_bsp(s, &b));
    assert_int_equal(b.leaf_count, 3);
    assert_int_equal(b.leaves[0].cluster, 0);
    assert_int_equal(b.leaves[1].cluster, 1);
    assert_int_equal(b.leaves[2].cluster, -1);
    assert_int_equal(b.leaves[2].object_count, 0);
    for (uint32_t k = 0; k < b.leaf_object_count; k++)
        assert_int_not_equal(b.leaf_objects[k], 6); /* the door */
    /* the reachable leaves keep their lists: leaf 0 {floor, sky, water}, leaf 1 {water, patch, mesh} */
    assert_int_equal(b.leaves[0].object_count, 3);
    assert_int_equal(b.leaves[1].object_count, 3);
    sl_scene_stats stats;
    sl_scene_get_stats(s, &stats);
    assert_int_equal(stats.object_count, 7);
    assert_false(sl_scene_object(s, 6).flags & SL_OBJECT_OCCLUDER);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
    assert_int_equal(sl_viewcells_count(vc), 2);
    const sl_viewcell *c0 = &sl_viewcells_data(vc)[0];
    assert_int_equal(c0->cluster, 0);
    assert_float_equal(c0->bounds.min.x, 0.0f, 1e-6f); /* leaf 0 alone: x from 0 to 4 m */
    assert_float_equal(c0->bounds.max.x, 4.0f, 1e-6f);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
    free(map);
}

static void test_node_renumbering(void **state)
{
    (void)state;
    bspw w = {0};
    shader(&w, "textures/test/wall", 0, 1);
    plane(&w, 1, 0, 0, 0), plane(&w, 0, 0, 1, 0), plane(&w, 0, 1, 0, 0);
    node(&w, 0, 2, -1); /* x >= 0: node 2, else leaf 0 */
    node(&w, 1, -3, -4); /* z >= 0: leaf 2, else leaf 3 */
    node(&w, 2, 1, -2); /* y >= 0: node 1, else leaf 1 */
    for (int l = 0; l < 4; l++)
        leaf(&w, l, -128, 128, 0, 0, 0, 0);
    float box[6] = {0};
    int32_t m0[4] = {0, 0, 0, 0};
    put(&w, L_MOD, box, sizeof box), put(&w, L_MOD, m0, sizeof m0);
    size_t size;
    uint8_t *map = bspw_finish(&w, &size);
    sl_scene s;
    sl_error err;
    sl_status st = sl_import_q3bsp_memory(map, size, "nodes.bsp", NULL, NULL, &s, &err);
    if (st != SL_OK)
        fail_msg("%s", err.message);
    sl_bsp_view bsp;
    assert_true(sl_scene_bsp(s, &bsp));
    assert_int_equal(bsp.node_count, 3);
    assert_int_equal(bsp.nodes[1].plane, 2); /* old node 2 is now second */
    assert_int_equal(bsp.nodes[0].children[0], 1);
    assert_int_equal(bsp.nodes[1].children[0], 2);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){-1, 0, 0}), 0);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){1, -1, 0}), 1);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){1, 1, 1}), 2);
    assert_int_equal(sl_scene_bsp_find_leaf(s, (sl_vec3){1, 1, -1}), 3);
    assert_int_equal(sl_scene_object_count(s), 0);
    assert_int_equal(bsp.cluster_count, 4); /* no vis: 1 + the largest leaf cluster */
    sl_scene_destroy(s);

    /* node 2 -> node 1 -> node 2: not a tree */
    poke_i(map, lump_at(map, L_NOD, 36, 1) + 4, 2);
    assert_int_equal(sl_import_q3bsp_memory(map, size, "nodes.bsp", NULL, NULL, &s, &err), SL_ERROR_FORMAT);
    assert_true(contains(err.message, "nodes.bsp: lump 3 (nodes): node 2 is reached twice"));
    free(map);
}

/* Each hostile edit of the tiny map fails with a format error naming the lump and element. */
static void test_tiny_hostile(void **state)
{
    (void)state;
    size_t size;
    uint8_t *good = tiny_map(&size, true);
    uint8_t *map = malloc(size);
    assert_non_null(map);
    sl_test_counter counter = {0};
    sl_allocator a = sl_test_counting_allocator(&counter);
    sl_scene s;
    sl_error err;
    const float nan = NAN;
    struct edit {
        int lump;
        size_t rec, index, field;
        int32_t value;
        bool is_float;
        float fvalue;
        sl_status expect;
        const char *message;
    } edits[] = {
        {-1, 0, 0, 0, 0x4b415551, false, 0, SL_ERROR_FORMAT, "offset 0: not a Quake III map (magic \"QUAK\""},
        {-1, 0, 0, 4, 47, false, 0, SL_ERROR_UNSUPPORTED, "IBSP version 47 is not supported"},
        {-1, 0, 0, 8 + 8 * L_FAC + 4, -104, false, 0, SL_ERROR_FORMAT, "lump 13 (faces): header offset 116: negative lump length -104"},
        {-1, 0, 0, 8 + 8 * L_FAC + 4, 103, false, 0, SL_ERROR_FORMAT, "lump 13 (faces): length 103 is not a multiple"},
        {-1, 0, 0, 8 + 8 * L_VRT, 0x7ffffff0, false, 0, SL_ERROR_FORMAT, "lump 10 (drawverts): offset 2147483632"},
        {L_FAC, 104, 0, 0, 3, false, 0, SL_ERROR_FORMAT, "lump 13 (faces): face 0: shader 3 out of range (3 shaders)"},
        {L_FAC, 104, 0, 8, 7, false, 0, SL_ERROR_FORMAT, "face 0: unknown surface type 7"},
        {L_FAC, 104, 0, 16, 0x7fffffff, false, 0, SL_ERROR_FORMAT, "face 0: vertex range 0+2147483647 outside"},
        {L_FAC, 104, 0, 20, -1, false, 0, SL_ERROR_FORMAT, "face 0: meshvert range -1+6 outside"},
        {L_FAC, 104, 0, 24, 5, false, 0, SL_ERROR_FORMAT, "face 0: 5 meshverts is not a whole number"},
        {L_MSV, 4, 1, 0, 4, false, 0, SL_ERROR_FORMAT, "face 0: meshvert 1 = 4 outside the face's 4 vertices"},
        {L_FAC, 104, 1, 96, 4, false, 0, SL_ERROR_FORMAT, "face 1: patch size 4x3 is not odd"},
        {L_FAC, 104, 1, 96, 1, false, 0, SL_ERROR_FORMAT, "face 1: patch size 1x3 is not odd"},
        {L_FAC, 104, 1, 100, 0x7fffffff, false, 0, SL_ERROR_FORMAT, "face 1: patch size 3x2147483647 does not match"},
        {L_VRT, 44, 2, 4, 0, true, NAN, SL_ERROR_FORMAT, "lump 10 (drawverts): vertex 2: position is not finite"},
        {L_VRT, 44, 5, 32, 0, true, INFINITY, SL_ERROR_FORMAT, "vertex 5: normal is not finite"},
        {L_PLN, 16, 1, 12, 0, true, NAN, SL_ERROR_FORMAT, "lump 2 (planes): plane 1: normal or distance is not finite"},
        {L_NOD, 36, 0, 0, 2, false, 0, SL_ERROR_FORMAT, "lump 3 (nodes): node 0: plane 2 out of range"},
        {L_NOD, 36, 0, 4, 1, false, 0, SL_ERROR_FORMAT, "node 0: child 1 out of range (1 nodes, 2 leaves)"},
        {L_NOD, 36, 0, 8, -3, false, 0, SL_ERROR_FORMAT, "node 0: child -3 out of range"},
        {L_NOD, 36, 0, 8, INT32_MIN, false, 0, SL_ERROR_FORMAT, "node 0: child -2147483648 out of range"},
        {L_LEF, 48, 1, 0, 2, false, 0, SL_ERROR_FORMAT, "lump 4 (leaves): leaf 1: cluster 2 out of range (2 clusters"},
        {L_LEF, 48, 1, 0, -2, false, 0, SL_ERROR_FORMAT, "leaf 1: cluster -2 out of range"},
        {L_LEF, 48, 1, 36, 5, false, 0, SL_ERROR_FORMAT, "leaf 1: leafface range 3+5 outside the 7 leaffaces"},
        {L_LEF, 48, 0, 36, 5, false, 0, SL_ERROR_FORMAT, "leaf 1: the leaves reference more leaffaces than"},
        {L_LEF, 48, 0, 44, 2, false, 0, SL_ERROR_FORMAT, "leaf 0: leafbrush range 0+2 outside"},
        {L_LFF, 4, 6, 0, 8, false, 0, SL_ERROR_FORMAT, "lump 5 (leaffaces): leafface 6: face 8 out of range (8 faces)"},
        {L_LFB, 4, 0, 0, -1, false, 0, SL_ERROR_FORMAT, "lump 6 (leafbrushes): leafbrush 0: brush -1 out of range"},
        {L_MOD, 40, 1, 24, 8, false, 0, SL_ERROR_FORMAT, "lump 7 (models): model 1: face range 8+1 outside the 8 faces"},
        {L_MOD, 40, 0, 28, 8, false, 0, SL_ERROR_FORMAT, "model 1: the models hold more faces than the 8"},
        {L_MOD, 40, 0, 36, 2, false, 0, SL_ERROR_FORMAT, "model 0: brush range 0+2 outside the 1 brushes"},
        {L_BRU, 12, 0, 4, 2, false, 0, SL_ERROR_FORMAT, "lump 8 (brushes): brush 0: side range 0+2 outside"},
        {L_BRS, 8, 0, 0, 2, false, 0, SL_ERROR_FORMAT, "lump 9 (brushsides): brushside 0: plane 2 out of range"},
        {L_VIS, 1, 0, 0, 3, false, 0, SL_ERROR_FORMAT, "lump 16 (visdata): 3 clusters x 1 bytes do not fit in 10 bytes"},
        {L_VIS, 1, 0, 0, -1, false, 0, SL_ERROR_FORMAT, "lump 16 (visdata): negative cluster count -1"},
        {L_VIS, 1, 0, 4, 0x40000000, false, 0, SL_ERROR_FORMAT, "2 clusters x 1073741824 bytes do not fit"},
        {L_VIS, 1, 0, 4, 0, false, 0, SL_ERROR_FORMAT, "rows of 0 bytes cannot hold 2 cluster bits"},
    };
    (void)nan;
    for (size_t e = 0; e < SL_COUNTOF(edits); e++) {
        memcpy(map, good, size);
        size_t at = edits[e].lump < 0 ? edits[e].field : lump_at(map, edits[e].lump, edits[e].rec, edits[e].index) + edits[e].field;
        if (edits[e].is_float)
            poke_f(map, at, edits[e].fvalue);
        else
            poke_i(map, at, edits[e].value);
        sl_status st = sl_import_q3bsp_memory(map, size, "tiny.bsp", NULL, &a, &s, &err);
        if (st != edits[e].expect || !contains(err.message, edits[e].message) || !contains(err.message, "tiny.bsp: "))
            fail_msg("edit %zu: status %d, message \"%s\"; expected \"%s\"", e, st, st ? err.message : "", edits[e].message);
        assert_null(s);
        assert_int_equal(counter.live, 0);
    }
    /* every truncation fails cleanly, and so does an empty buffer */
    for (size_t n = 0; n < size - 2; n++) {
        sl_status st = sl_import_q3bsp_memory(good, n, "tiny.bsp", NULL, &a, &s, &err);
        if (st != SL_ERROR_FORMAT)
            fail_msg("truncated at %zu: status %d", n, st);
    }
    assert_int_equal(sl_import_q3bsp_memory(NULL, 0, "tiny.bsp", NULL, &a, &s, &err), SL_ERROR_FORMAT);
    assert_int_equal(counter.live, 0);

    /* a patch that would tessellate past the triangle budget is refused before allocating */
    assert_int_equal(sl_q3bsp_import_memory_limited(good, size, "tiny.bsp", NULL, 100, &a, &s, &err), SL_ERROR_LIMIT);
    assert_true(contains(err.message, "face 1: the map needs more than 100 triangles"));
    assert_int_equal(counter.live, 0);
    free(map);
    free(good);
}

/* ---- .pk3 archives ---- */

static char *temp_path(const char *suffix)
{
    char *p = malloc(256);
    assert_non_null(p);
    snprintf(p, 256, "%s/test_q3bsp_%ld%s", SL_BINARY_DIR, (long)getpid(), suffix);
    return p;
}

static void write_file(const char *path, const void *data, size_t size)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(data, 1, size, fp), size);
    assert_int_equal(fclose(fp), 0);
}

/* Write a zip holding `map` as entry `entry` (stored or deflated) and a text file. */
static void write_pk3(const char *path, const char *entry, const void *map, size_t size, bool deflate)
{
    int zerr;
    zip_t *z = zip_open(path, ZIP_CREATE | ZIP_TRUNCATE, &zerr);
    assert_non_null(z);
    zip_source_t *src = zip_source_buffer(z, map, size, 0);
    assert_non_null(src);
    zip_int64_t idx = zip_file_add(z, entry, src, ZIP_FL_OVERWRITE);
    assert_true(idx >= 0);
    assert_int_equal(zip_set_file_compression(z, (zip_uint64_t)idx, deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE, 0), 0);
    static const char readme[] = "not a map\n";
    zip_source_t *txt = zip_source_buffer(z, readme, sizeof readme - 1, 0);
    assert_true(zip_file_add(z, "readme.txt", txt, 0) >= 0);
    assert_int_equal(zip_close(z), 0);
}

static uint8_t *read_file(const char *path, size_t *size)
{
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    *size = (size_t)ftell(fp);
    fseek(fp, 0, SEEK_SET);
    uint8_t *p = malloc(*size);
    assert_non_null(p);
    assert_int_equal(fread(p, 1, *size, fp), *size);
    fclose(fp);
    return p;
}

static void test_pk3(void **state)
{
    (void)state;
    size_t size;
    uint8_t *map = tiny_map(&size, true);
    char *pk3 = temp_path(".pk3"), *bsp = temp_path(".bsp");
    write_pk3(pk3, "maps/tiny.bsp", map, size, true);
    write_file(bsp, map, size);
    sl_error err;
    sl_scene s;

    sl_test_name_list list = {0};
    assert_int_equal(sl_pk3_list_maps(pk3, sl_test_collect_name, &list, &err), SL_OK);
    assert_int_equal(list.count, 1);
    assert_string_equal(list.names[0], "maps/tiny.bsp");

    const char *names[] = {"tiny", "tiny.bsp", "maps/tiny", "maps/tiny.bsp", "MAPS/TINY.BSP", NULL, ""};
    for (size_t i = 0; i < SL_COUNTOF(names); i++) {
        sl_status st = sl_import_q3bsp(pk3, names[i], NULL, NULL, &s, &err);
        if (st != SL_OK)
            fail_msg("%s: %s", names[i] ? names[i] : "(null)", err.message);
        assert_int_equal(sl_scene_object_count(s), 7);
        char want[300];
        snprintf(want, sizeof want, "%s:maps/tiny.bsp", strrchr(pk3, '/') + 1);
        assert_string_equal(sl_scene_meta(s, "source"), want);
        assert_string_equal(sl_scene_meta(s, "q3.map"), "tiny");
        sl_scene_destroy(s);
    }
    /* a plain .bsp file: the map argument is ignored */
    assert_int_equal(sl_import_q3bsp(bsp, "whatever", NULL, NULL, &s, &err), SL_OK);
    assert_string_equal(sl_scene_meta(s, "source"), strrchr(bsp, '/') + 1);
    sl_scene_destroy(s);

    assert_int_equal(sl_import_q3bsp(pk3, "nosuch", NULL, NULL, &s, &err), SL_ERROR_NOT_FOUND);
    assert_true(contains(err.message, pk3) && contains(err.message, "entry maps/nosuch.bsp not found"));
    assert_int_equal(sl_import_q3bsp(pk3, "textures/x.jpg", NULL, NULL, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_import_q3bsp("/nonexistent/q3.pk3", "x", NULL, NULL, &s, &err), SL_ERROR_NOT_FOUND);
    assert_int_equal(sl_pk3_list_maps(bsp, sl_test_collect_name, &list, &err), SL_ERROR_FORMAT);
    assert_true(contains(err.message, "not a zip archive"));

    /* the size limit is checked before reading, and named with archive and entry */
    size_t zsize;
    uint8_t *zip = read_file(pk3, &zsize);
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "mem.pk3", "tiny", 100, SL_Q3_MAX_TRIANGLES, NULL, NULL, &s, &err),
                     SL_ERROR_LIMIT);
    assert_true(contains(err.message, "mem.pk3: entry maps/tiny.bsp: uncompressed size"));
    list.count = 0;
    assert_int_equal(sl_pk3_list_maps_memory(zip, zsize, "mem.pk3", sl_test_collect_name, &list, &err), SL_OK);
    assert_int_equal(list.count, 1);
    /* every truncation of the archive fails cleanly */
    for (size_t n = 0; n < zsize; n += 7) {
        sl_status st = sl_pk3_import_memory(zip, n, "mem.pk3", "tiny", SL_PK3_MAX_ENTRY_BYTES, SL_Q3_MAX_TRIANGLES, NULL,
                                            NULL, &s, &err);
        assert_int_not_equal(st, SL_OK);
        assert_null(s);
    }
    free(zip);

    /* a stored entry with one flipped byte: the CRC check catches it */
    write_pk3(pk3, "maps/tiny.bsp", map, size, false);
    zip = read_file(pk3, &zsize);
    uint16_t name_len, extra_len;
    memcpy(&name_len, zip + 26, 2);
    memcpy(&extra_len, zip + 28, 2);
    zip[30 + name_len + extra_len + 200] ^= 0x5a;
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "mem.pk3", "tiny", SL_PK3_MAX_ENTRY_BYTES, SL_Q3_MAX_TRIANGLES,
                                          NULL, NULL, &s, &err),
                     SL_ERROR_FORMAT);
    assert_true(contains(err.message, "mem.pk3: entry maps/tiny.bsp"));
    free(zip);

    remove(pk3);
    remove(bsp);
    free(pk3);
    free(bsp);
    free(map);
}

/* ---- the OpenArena maps ---- */

/* Read an entry of the OpenArena archive into memory. */
static uint8_t *oa_entry(const char *entry, size_t *size)
{
    int zerr;
    zip_t *z = zip_open(OA_PK3, ZIP_RDONLY, &zerr);
    assert_non_null(z);
    zip_stat_t st;
    assert_int_equal(zip_stat(z, entry, 0, &st), 0);
    zip_file_t *f = zip_fopen(z, entry, 0);
    assert_non_null(f);
    uint8_t *p = malloc(st.size);
    assert_non_null(p);
    assert_int_equal(zip_fread(f, p, st.size), (zip_int64_t)st.size);
    zip_fclose(f);
    zip_discard(z);
    *size = st.size;
    return p;
}

static bool have_openarena(void)
{
    if (access(OA_PK3, R_OK) == 0)
        return true;
    print_message("skipped: %s is not installed (Debian package openarena-081-maps)\n", OA_PK3);
    return false;
}

/* The fraction of triangles turned counter-clockwise towards their vertex normals. */
static double front_facing_fraction(sl_scene s)
{
    uint64_t agree = 0, total = 0;
    for (uint32_t m = 0; m < sl_scene_mesh_count(s); m++) {
        sl_mesh_view v = sl_scene_mesh(s, m);
        for (uint32_t t = 0; t < v.triangle_count; t++) {
            const uint32_t *ix = v.indices + 3 * t;
            const float *p0 = v.positions + 3 * ix[0], *p1 = v.positions + 3 * ix[1], *p2 = v.positions + 3 * ix[2];
            float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]}, e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
            float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            if (n[0] * n[0] + n[1] * n[1] + n[2] * n[2] < 1e-12f)
                continue; /* collapsed patch edges */
            float d = 0;
            for (int k = 0; k < 3; k++)
                d += n[k] * (v.normals[3 * ix[0] + k] + v.normals[3 * ix[1] + k] + v.normals[3 * ix[2] + k]);
            agree += d > 0;
            total++;
        }
    }
    return total ? (double)agree / (double)total : 0;
}

static void test_openarena_maps(void **state)
{
    (void)state;
    if (!have_openarena())
        skip();
    sl_test_name_list list = {0};
    sl_error err;
    assert_int_equal(sl_pk3_list_maps(OA_PK3, sl_test_collect_name, &list, &err), SL_OK);
    assert_true(list.count >= 40);
    bool sanitized = getenv("SL_SANITIZED") != NULL;
    double t0 = sl_now();
    uint64_t total_tris = 0;
    for (int i = 0; i < list.count; i++) {
        /* under the sanitizers every fifth map is plenty */
        if (sanitized && i % 5)
            continue;
        sl_scene s;
        sl_status st = sl_import_q3bsp(OA_PK3, list.names[i], NULL, NULL, &s, &err);
        if (st != SL_OK)
            fail_msg("%s", err.message);
        sl_scene_stats stats;
        sl_scene_get_stats(s, &stats);
        sl_bsp_view bsp;
        assert_true(sl_scene_bsp(s, &bsp));
        assert_true(stats.triangle_count > 0);
        assert_true(stats.object_count > 0);
        assert_true(bsp.leaf_count > 0);
        assert_true(bsp.cluster_count > 0);
        assert_true(bsp.node_count > 0);
        bool has_vis = strcmp(sl_scene_meta(s, "q3.has_vis"), "yes") == 0;
        assert_int_equal(bsp.pvs != NULL, has_vis);
        double front = front_facing_fraction(s);
        if (front < 0.95)
            fail_msg("%s: only %.3f of the triangles face their normals", list.names[i], front);
        /* every spawn point lies in a leaf of some cluster */
        const char *sp = sl_scene_meta(s, "q3.spawns");
        unsigned spawns = 0;
        while (sp && *sp) {
            sl_vec3 p;
            int used;
            assert_int_equal(sscanf(sp, "%f %f %f%n", &p.x, &p.y, &p.z, &used), 3);
            sp += used + (sp[used] == ';');
            int32_t l = sl_scene_bsp_find_leaf(s, p);
            assert_true(l >= 0 && (uint32_t)l < bsp.leaf_count);
            if (bsp.leaves[l].cluster < 0)
                fail_msg("%s: spawn %.2f %.2f %.2f is in leaf %d outside every cluster", list.names[i], p.x, p.y, p.z, l);
            spawns++;
        }
        assert_int_equal(spawns, (unsigned)atoi(sl_scene_meta(s, "q3.spawn_count")));
        print_message("%-26s %7llu triangles %5u objects %5u leaves %5u clusters vis %-3s %3u spawns\n", list.names[i],
                      (unsigned long long)stats.triangle_count, stats.object_count, bsp.leaf_count, bsp.cluster_count,
                      has_vis ? "yes" : "no", spawns);
        total_tris += stats.triangle_count;
        sl_scene_destroy(s);
    }
    print_message("imported in %.2f s, %llu triangles\n", sl_now() - t0, (unsigned long long)total_tris);
}

/* The PVS is the map's own, byte for byte, and memory and archive imports agree. */
static void test_openarena_pvs(void **state)
{
    (void)state;
    if (!have_openarena())
        skip();
    size_t size;
    uint8_t *map = oa_entry("maps/oa_dm1.bsp", &size);
    sl_scene s, t;
    sl_error err;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "oa_dm1.bsp", NULL, NULL, &s, &err), SL_OK);
    assert_int_equal(sl_import_q3bsp(OA_PK3, "oa_dm1", NULL, NULL, &t, &err), SL_OK);
    sl_bsp_view b;
    assert_true(sl_scene_bsp(s, &b));
    const uint8_t *vis = map + lump_at(map, L_VIS, 1, 0);
    int32_t nvec, sz;
    memcpy(&nvec, vis, 4);
    memcpy(&sz, vis + 4, 4);
    assert_int_equal(b.cluster_count, (uint32_t)nvec);
    assert_int_equal(b.cluster_bytes, (uint32_t)sz);
    assert_memory_equal(b.pvs, vis + 8, (size_t)nvec * (size_t)sz);
    assert_null(sl_scene_meta(s, "q3.farplanedist")); /* oa_dm1 sets no vis far plane */
    sl_scene_stats a, c;
    sl_scene_get_stats(s, &a);
    sl_scene_get_stats(t, &c);
    assert_int_equal(a.triangle_count, c.triangle_count);
    assert_int_equal(a.object_count, c.object_count);
    for (uint32_t o = 0; o < a.object_count; o++)
        assert_int_equal(sl_scene_object(s, o).color, sl_scene_object(t, o).color);
    sl_scene_destroy(s);
    sl_scene_destroy(t);
    free(map);
}

/* Triangles each face of a map tessellates to at bezier level 8, read from the raw bytes. */
static uint32_t face_triangles(const uint8_t *map, uint32_t f)
{
    int32_t v[26];
    memcpy(v, map + lump_at(map, L_FAC, 104, f), sizeof v);
    if (v[2] == 1 || v[2] == 3)
        return (uint32_t)v[6] / 3;
    if (v[2] == 2)
        return 2 * (uint32_t)((v[24] - 1) / 2 * 8) * (uint32_t)((v[25] - 1) / 2 * 8);
    return 0;
}

/* Objects: one face per object at split 1; at the default split no object exceeds 2048
 * triangles unless it is a single larger face; the triangles are the same either way. */
static void test_openarena_split(void **state)
{
    (void)state;
    if (!have_openarena())
        skip();
    size_t size;
    uint8_t *map = oa_entry("maps/dm6ish.bsp", &size);
    int32_t faces_len;
    memcpy(&faces_len, map + 12 + 8 * L_FAC, 4);
    uint32_t nfaces = (uint32_t)faces_len / 104, drawn = 0, largest = 0;
    uint64_t tris = 0;
    for (uint32_t f = 0; f < nfaces; f++) {
        uint32_t t = face_triangles(map, f);
        drawn += t > 0;
        tris += t;
        largest = SL_MAX(largest, t);
    }
    sl_import_options opt = sl_import_defaults();
    opt.split_triangles = 1;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "dm6ish", &opt, NULL, &s, &err), SL_OK);
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    assert_int_equal(st.object_count, drawn);
    assert_int_equal(st.triangle_count, tris);
    sl_scene_destroy(s);

    opt.split_triangles = 300;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "dm6ish", &opt, NULL, &s, &err), SL_OK);
    sl_scene_get_stats(s, &st);
    assert_int_equal(st.triangle_count, tris);
    assert_true(st.object_count < drawn);
    for (uint32_t o = 0; o < st.object_count; o++)
        assert_true(sl_scene_object(s, o).triangle_count <= SL_MAX(300u, largest));
    sl_scene_destroy(s);
    free(map);
}

/* Real maps cut short, with broken lump headers, inflated counts and random damage. */
static void test_openarena_hostile(void **state)
{
    (void)state;
    if (!have_openarena())
        skip();
    size_t size;
    uint8_t *good = oa_entry("maps/dm6ish.bsp", &size); /* has patches */
    uint8_t *map = malloc(size);
    assert_non_null(map);
    sl_test_counter counter = {0};
    sl_allocator a = sl_test_counting_allocator(&counter);
    sl_scene s;
    sl_error err;
    bool sanitized = getenv("SL_SANITIZED") != NULL;

    /* truncation: at every lump boundary and at spread offsets below the end of the last lump */
    size_t end = 0;
    for (int k = 0; k < L_COUNT; k++) {
        int32_t off, len;
        memcpy(&off, good + 8 + 8 * k, 4);
        memcpy(&len, good + 12 + 8 * k, 4);
        end = SL_MAX(end, (size_t)off + (size_t)len);
    }
    for (int k = 0; k < L_COUNT; k++) {
        int32_t off, len;
        memcpy(&off, good + 8 + 8 * k, 4);
        memcpy(&len, good + 12 + 8 * k, 4);
        size_t cuts[4] = {(size_t)off, (size_t)off + 1, (size_t)off + (size_t)len - 1, (size_t)off + (size_t)len};
        for (int i = 0; i < 4; i++)
            if (cuts[i] < end)
                assert_int_equal(sl_import_q3bsp_memory(good, cuts[i], "cut.bsp", NULL, &a, &s, &err), SL_ERROR_FORMAT);
    }
    sl_rng rng;
    sl_rng_seed(&rng, 46, 1);
    for (int i = 0; i < (sanitized ? 40 : 200); i++) {
        size_t n = sl_rng_below(&rng, (uint32_t)end);
        assert_int_equal(sl_import_q3bsp_memory(good, n, "cut.bsp", NULL, &a, &s, &err), SL_ERROR_FORMAT);
        assert_true(contains(err.message, "cut.bsp: "));
    }

    /* lump headers: offset past the end, negative offset or length, partial record, a count one
     * record beyond what the rest of the file holds */
    const size_t records[L_COUNT] = {1, 72, 16, 36, 48, 4, 4, 40, 12, 8, 44, 4, 72, 104, 49152, 8, 1};
    for (int k = 0; k < L_COUNT; k++) {
        int32_t off, len;
        memcpy(&off, good + 8 + 8 * k, 4);
        memcpy(&len, good + 12 + 8 * k, 4);
        int32_t inflated = (int32_t)(((size - (size_t)off) / records[k] + 1) * records[k]);
        int32_t values[5][2] = {{(int32_t)size + 4, len}, {-8, len}, {off, -4}, {off, inflated}, {off, len - 1}};
        char prefix[32];
        snprintf(prefix, sizeof prefix, "lump %d (", k);
        for (int v = 0; v < 5; v++) {
            if (v == 4 && (records[k] == 1 || len == 0))
                continue; /* free-form lumps have no partial records */
            memcpy(map, good, size);
            poke_i(map, 8 + 8 * (size_t)k, values[v][0]);
            poke_i(map, 12 + 8 * (size_t)k, values[v][1]);
            sl_status st = sl_import_q3bsp_memory(map, size, "hdr.bsp", NULL, &a, &s, &err);
            if (st != SL_ERROR_FORMAT || !contains(err.message, prefix))
                fail_msg("lump %d edit %d: status %d: %s", k, v, st, err.message);
        }
    }

    /* inflated counts and indices inside records */
    uint32_t patch = 0;
    while (true) {
        int32_t type;
        memcpy(&type, good + lump_at(good, L_FAC, 104, patch) + 8, 4);
        if (type == 2)
            break;
        patch++;
    }
    struct {
        int lump;
        size_t rec, index, field;
        int32_t value;
        const char *message;
    } edits[] = {
        {L_FAC, 104, 0, 16, 0x7fffffff, "face 0: vertex range"},
        {L_FAC, 104, 0, 24, 0x7ffffffe, "face 0: meshvert range"},
        {L_FAC, 104, 0, 0, 0x10000, "face 0: shader 65536 out of range"},
        {L_FAC, 104, patch, 96, 0x7fffffff, "patch size 2147483647x"},
        {L_FAC, 104, patch, 100, 0x10001, "does not match its"},
        {L_LEF, 48, 0, 36, 0x7fffffff, "leaf 0: leafface range"},
        {L_LEF, 48, 3, 0, 0x7fffffff, "leaf 3: cluster 2147483647 out of range"},
        {L_NOD, 36, 0, 4, 1 << 30, "node 0: child 1073741824 out of range"},
        {L_NOD, 36, 5, 0, -5, "node 5: plane -5 out of range"},
        {L_MOD, 40, 0, 28, 0x7fffffff, "model 0: face range"},
        {L_LFF, 4, 0, 0, -1, "leafface 0: face -1 out of range"},
        {L_VIS, 1, 0, 0, 0x7fffffff, "lump 16 (visdata)"},
        {L_MSV, 4, 0, 0, 1 << 20, "outside the face's"},
    };
    for (size_t e = 0; e < SL_COUNTOF(edits); e++) {
        memcpy(map, good, size);
        poke_i(map, lump_at(map, edits[e].lump, edits[e].rec, edits[e].index) + edits[e].field, edits[e].value);
        sl_status st = sl_import_q3bsp_memory(map, size, "dm6ish.bsp", NULL, &a, &s, &err);
        if (st != SL_ERROR_FORMAT || !contains(err.message, edits[e].message))
            fail_msg("edit %zu: status %d: %s (expected \"%s\")", e, st, err.message, edits[e].message);
    }

    /* random damage: anything but a crash, a leak or a partial scene */
    for (int i = 0; i < (sanitized ? 30 : 150); i++) {
        memcpy(map, good, size);
        int hits = 1 + (int)sl_rng_below(&rng, 8);
        for (int h = 0; h < hits; h++) {
            /* half of the hits land in the header and the index-heavy lumps near the start */
            size_t at = sl_rng_below(&rng, 2) ? sl_rng_below(&rng, (uint32_t)SL_MIN(size, (size_t)200000))
                                              : sl_rng_below(&rng, (uint32_t)size);
            map[at] = (uint8_t)sl_rng_u32(&rng);
        }
        sl_status st = sl_import_q3bsp_memory(map, size, "noise.bsp", NULL, &a, &s, &err);
        assert_true(st == SL_OK || st == SL_ERROR_FORMAT || st == SL_ERROR_UNSUPPORTED || st == SL_ERROR_LIMIT);
        if (st == SL_OK)
            sl_scene_destroy(s);
        else
            assert_null(s);
        assert_int_equal(counter.live, 0);
    }
    free(map);
    free(good);
}

/* ---- issue 12: readers that trusted too much ---- */

/* Spawn classes of Nexuiz (and Xonotic): team spawns and race starts are spawn points too. */
static void test_spawn_classes(void **state)
{
    (void)state;
    const char *ents = "{\n\"classname\" \"worldspawn\"\n}\n"
                       "{\n\"classname\" \"info_player_team1\"\n\"origin\" \"32 0 16\"\n}\n"
                       "{\n\"classname\" \"info_player_team2\"\n\"origin\" \"64 0 16\"\n}\n"
                       "{\n\"classname\" \"info_player_team3\"\n\"origin\" \"96 0 16\"\n}\n"
                       "{\n\"classname\" \"info_player_team4\"\n\"origin\" \"128 0 16\"\n}\n"
                       "{\n\"origin\" \"-64 0 16\"\n\"classname\" \"info_player_race\"\n}\n"
                       "{\n\"classname\" \"info_player_nosuch\"\n\"origin\" \"0 0 0\"\n}\n"
                       "{\n\"classname\" \"func_door\"\n\"model\" \"*1\"\n}\n";
    size_t size;
    uint8_t *map = tiny_map_ents(&size, true, false, ents);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "teams.bsp", NULL, NULL, &s, &err), SL_OK);
    assert_string_equal(sl_scene_meta(s, "q3.spawn_count"), "5");
    assert_string_equal(sl_scene_meta(s, "q3.spawns"),
                        "1.0000 0.0000 0.5000;2.0000 0.0000 0.5000;3.0000 0.0000 0.5000;4.0000 0.0000 0.5000;"
                        "-2.0000 0.0000 0.5000");
    /* and street views, which stand on the spawn points of a map without streets, now exist */
    sl_path p;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 4, 7, NULL, NULL, &p, &err), SL_OK);
    assert_int_equal(sl_path_count(p), 4);
    sl_path_destroy(p);
    sl_scene_destroy(s);
    free(map);
}

/* Node and leaf boxes are integers in the file; a unit scale that makes them infinite is refused
 * against the lump and the element (and a scene's NaN boxes by sl_scene_set_bsp and the .slscene
 * reader: test_slscene). */
static void test_bsp_boxes(void **state)
{
    (void)state;
    size_t size;
    uint8_t *map = tiny_map(&size, true);
    sl_import_options o = sl_import_defaults();
    o.unit_scale = 1e37f;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_q3bsp_memory(map, size, "huge.bsp", &o, NULL, &s, &err), SL_ERROR_FORMAT);
    if (!contains(err.message, "huge.bsp: lump 3 (nodes): node 0: mins.x (-128) is not finite once scaled"))
        fail_msg("%s", err.message);
    free(map);
    /* the library's own check, for any scene */
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_plane pl = {0, 0, 1, 0};
    sl_bsp_node nd = {0, {-1, -2}, {{0, 0, 0}, {1, 1, 1}}};
    sl_bsp_leaf lf[2] = {{-1, 0, {{0, 0, 0}, {1, 1, 1}}, 0, 0}, {-1, 0, {{0, 0, 0}, {1, 1, 1}}, 0, 0}};
    sl_bsp_desc d = {0};
    d.planes = &pl, d.plane_count = 1, d.nodes = &nd, d.node_count = 1, d.leaves = lf, d.leaf_count = 2;
    assert_int_equal(sl_scene_set_bsp(s, &d, &err), SL_OK);
    nd.bounds.max.y = NAN;
    assert_int_equal(sl_scene_set_bsp(s, &d, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_true(contains(err.message, "bsp node 0: maxs.y is NaN"));
    nd.bounds.max.y = 1;
    lf[1].bounds.min.z = -INFINITY;
    assert_int_equal(sl_scene_set_bsp(s, &d, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_true(contains(err.message, "bsp leaf 1: mins.z is infinite"));
    sl_scene_destroy(s);
}

typedef struct capped {
    size_t live, cap;
} capped;
static void *cap_alloc(void *u, size_t size, size_t align)
{
    capped *c = u;
    void *p = NULL;
    if (size > c->cap - c->live || posix_memalign(&p, align < sizeof(void *) ? sizeof(void *) : align, size ? size : 1))
        return NULL;
    c->live += size;
    return p;
}
static void cap_free(void *u, void *ptr, size_t size)
{
    capped *c = u;
    c->live -= size;
    free(ptr);
}
static void *cap_realloc(void *u, void *ptr, size_t old_size, size_t new_size, size_t align)
{
    void *p = cap_alloc(u, new_size, align);
    if (p && ptr) {
        memcpy(p, ptr, SL_MIN(old_size, new_size));
        cap_free(u, ptr, old_size);
    }
    return p;
}

/* One 99x99 patch (9801 control points, 431 KB) that `faces` faces all reference. */
static uint8_t *shared_patch_map(size_t *size, int faces)
{
    bspw w = {0};
    const char *ents = "{\n\"classname\" \"worldspawn\"\n}\n";
    put(&w, L_ENT, ents, strlen(ents) + 1);
    shader(&w, "textures/test/wall", 0, 1);
    plane(&w, 0, 0, 1, 0);
    leaf(&w, 0, -4096, 4096, 0, 0, 0, 0);
    float box[6] = {-4096, -4096, -128, 4096, 4096, 128};
    int32_t m0[4] = {0, faces, 0, 0};
    put(&w, L_MOD, box, sizeof box), put(&w, L_MOD, m0, sizeof m0);
    for (int j = 0; j < 99; j++)
        for (int i = 0; i < 99; i++)
            vert(&w, 16.0f * i, 16.0f * j, (float)((i * 7 + j * 3) % 5), 0, 0, 1);
    for (int f = 0; f < faces; f++)
        face(&w, 0, 2, 0, 99 * 99, 0, 0, 99, 99);
    return bspw_finish(&w, size);
}

/* A small map must not expand without bound: 200 faces sharing one 99x99 patch asked for 61.5 M
 * triangles (1.47 GB) from 455 KB; the output is now bounded by the file's size. The importer
 * runs under a 256 MB allocator cap so that the unbounded version fails fast (out of memory)
 * instead of succeeding slowly. */
static void test_patch_expansion(void **state)
{
    (void)state;
    size_t size;
    uint8_t *map = shared_patch_map(&size, 200);
    assert_true(size > 440000 && size < 470000);
    capped cap = {0, (size_t)256 << 20};
    sl_allocator a = {cap_alloc, cap_realloc, cap_free, &cap};
    sl_scene s;
    sl_error err;
    sl_status st = sl_import_q3bsp_memory(map, size, "shared.bsp", NULL, &a, &s, &err);
    if (st != SL_ERROR_LIMIT)
        fail_msg("status %d: %s", st, st == SL_OK ? "imported" : err.message);
    /* 307 328 triangles a face at level 8; the bound for ~452 KB is ~970 k: face 3 is the first too many */
    assert_true(contains(err.message, "shared.bsp: lump 13 (faces): face 3: "));
    assert_true(contains(err.message, "more than 970328 triangles at bezier level 8, the limit for a 452396-byte map"));
    assert_true(contains(err.message, "-byte map"));
    assert_null(s);
    assert_int_equal(cap.live, 0);
    free(map);
    /* the same patch used once is a legitimate (large) map: 307 328 triangles */
    map = shared_patch_map(&size, 1);
    assert_int_equal(sl_import_q3bsp_memory(map, size, "one.bsp", NULL, &a, &s, &err), SL_OK);
    sl_scene_stats stats;
    sl_scene_get_stats(s, &stats);
    assert_int_equal(stats.triangle_count, 2ull * 392 * 392);
    sl_scene_destroy(s);
    free(map);
}

/* Replace every occurrence of `from` by `to` (same length) in a buffer. */
static void replace_all(uint8_t *p, size_t n, const char *from, const char *to)
{
    size_t k = strlen(from);
    assert_int_equal(strlen(to), k);
    for (size_t i = 0; i + k <= n; i++)
        if (memcmp(p + i, from, k) == 0)
            memcpy(p + i, to, k);
}

/* A .pk3 holding two entries of one name is refused with that name, not libzip's bare "File
 * already exists"; a map in a subfolder loads under the name --list-maps prints, with or without
 * ".bsp" (Nexuiz's maps/_init/_init). */
static void test_pk3_names(void **state)
{
    (void)state;
    size_t msize;
    uint8_t *map = tiny_map(&msize, true);
    char *pk3 = temp_path(".pk3");
    int zerr;
    zip_t *z = zip_open(pk3, ZIP_CREATE | ZIP_TRUNCATE, &zerr);
    assert_non_null(z);
    const char *entries[] = {"maps/dupe.bsp", "maps/twin.bsp", "maps/_init/_init.bsp"};
    for (size_t i = 0; i < SL_COUNTOF(entries); i++) {
        zip_source_t *src = zip_source_buffer(z, map, msize, 0);
        assert_non_null(src);
        assert_true(zip_file_add(z, entries[i], src, 0) >= 0);
    }
    assert_int_equal(zip_close(z), 0);
    size_t zsize;
    uint8_t *zip = read_file(pk3, &zsize);
    unlink(pk3);
    free(pk3);
    sl_scene s;
    sl_error err;
    /* the subfolder map, as listed and without its extension */
    sl_test_name_list list = {0};
    assert_int_equal(sl_pk3_list_maps_memory(zip, zsize, "names.pk3", sl_test_collect_name, &list, &err), SL_OK);
    assert_int_equal(list.count, 3);
    assert_string_equal(list.names[2], "maps/_init/_init.bsp");
    const char *names[] = {"maps/_init/_init.bsp", "maps/_init/_init", "MAPS/_INIT/_INIT"};
    for (size_t i = 0; i < SL_COUNTOF(names); i++) {
        if (sl_pk3_import_memory(zip, zsize, "names.pk3", names[i], SL_PK3_MAX_ENTRY_BYTES, SL_Q3_MAX_TRIANGLES, NULL,
                                 NULL, &s, &err) != SL_OK)
            fail_msg("%s: %s", names[i], err.message);
        sl_scene_destroy(s);
    }
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "names.pk3", "maps/_init/other", SL_PK3_MAX_ENTRY_BYTES,
                                          SL_Q3_MAX_TRIANGLES, NULL, NULL, &s, &err),
                     SL_ERROR_NOT_FOUND);
    assert_true(contains(err.message, "entry maps/_init/other.bsp not found"));
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "names.pk3", "maps/_init/x.jpg", SL_PK3_MAX_ENTRY_BYTES,
                                          SL_Q3_MAX_TRIANGLES, NULL, NULL, &s, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    /* two entries of one name: the local headers and the central directory both say dupe */
    replace_all(zip, zsize, "maps/twin.bsp", "maps/dupe.bsp");
    assert_int_equal(sl_pk3_list_maps_memory(zip, zsize, "dupe.pk3", sl_test_collect_name, &list, &err), SL_ERROR_FORMAT);
    if (!contains(err.message, "dupe.pk3: duplicate entry maps/dupe.bsp"))
        fail_msg("%s", err.message);
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "dupe.pk3", "dupe", SL_PK3_MAX_ENTRY_BYTES, SL_Q3_MAX_TRIANGLES,
                                          NULL, NULL, &s, &err),
                     SL_ERROR_FORMAT);
    assert_true(contains(err.message, "dupe.pk3: duplicate entry maps/dupe.bsp"));
    /* a control character in the doubled name is escaped */
    replace_all(zip, zsize, "maps/dupe.bsp", "maps/d\x1bpe.bsp");
    assert_int_equal(sl_pk3_list_maps_memory(zip, zsize, "esc.pk3", sl_test_collect_name, &list, &err), SL_ERROR_FORMAT);
    assert_true(contains(err.message, "duplicate entry maps/d\\x1bpe.bsp"));
    assert_false(contains(err.message, "\x1b"));
    free(zip);
    free(map);
}

/* Entry names come from the archive: the messages of the pk3 reader (an entry over the size
 * limit) and of the map reader (a map too short for its header) escape them, so that an escape
 * sequence or a newline in a name never reaches the terminal raw. */
static void test_pk3_escaped_names(void **state)
{
    (void)state;
    /* libzip hands names that are not UTF-8 over as CP437 turned to UTF-8 (ESC becomes an arrow),
     * but UTF-8 ones as they are: a C1 CSI (U+009B), CR and LF reach the messages */
    static const char evil[] = "maps/e\xc2\x9b" "31mvil\r\nname\x7f.bsp";
    static const char shown[] = "maps/e\\xc2\\x9b" "31mvil\\x0d\\x0aname\\x7f.bsp";
    char *pk3 = temp_path(".pk3");
    int zerr;
    zip_t *z = zip_open(pk3, ZIP_CREATE | ZIP_TRUNCATE, &zerr);
    assert_non_null(z);
    static const char junk[] = "not a map, too short for the header";
    zip_source_t *src = zip_source_buffer(z, junk, sizeof junk - 1, 0);
    assert_non_null(src);
    assert_true(zip_file_add(z, evil, src, ZIP_FL_ENC_RAW) >= 0);
    assert_int_equal(zip_close(z), 0);
    size_t zsize;
    uint8_t *zip = read_file(pk3, &zsize);
    unlink(pk3);
    free(pk3);
    sl_scene s;
    sl_error err;
    /* the pk3 reader: over the entry size limit */
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "evil.pk3", NULL, 8, SL_Q3_MAX_TRIANGLES, NULL, NULL, &s, &err),
                     SL_ERROR_LIMIT);
    if (!contains(err.message, shown) || contains(err.message, "\x9b") || contains(err.message, "\n") ||
        contains(err.message, "\r") || contains(err.message, "\x7f"))
        fail_msg("pk3 reader: '%s' does not name the entry escaped (%s)", err.message, shown);
    /* the map reader: its name is "archive:entry" */
    assert_int_equal(sl_pk3_import_memory(zip, zsize, "evil.pk3", NULL, SL_PK3_MAX_ENTRY_BYTES, SL_Q3_MAX_TRIANGLES,
                                          NULL, NULL, &s, &err),
                     SL_ERROR_FORMAT);
    if (!contains(err.message, shown) || contains(err.message, "\x9b") || contains(err.message, "\n") ||
        contains(err.message, "\r") || contains(err.message, "\x7f"))
        fail_msg("map reader: '%s' does not name the entry escaped (%s)", err.message, shown);
    assert_true(contains(err.message, "evil.pk3:maps/e"));
    free(zip);
}

/* Every map of Nexuiz (the Debian package nexuiz-data, when installed; skipped otherwise) loads
 * under the name the archive lists, and the maps that have spawn points give random street views. */
static void test_nexuiz_maps(void **state)
{
    (void)state;
    glob_t g;
    if (glob("/usr/share/games/nexuiz/data/*.pk3", 0, NULL, &g) != 0) {
        skip();
        return;
    }
    bool sanitized = getenv("SL_SANITIZED") != NULL;
    unsigned maps = 0, loaded = 0, with_views = 0, seen = 0;
    for (size_t k = 0; k < g.gl_pathc; k++) {
        sl_test_name_list list = {0};
        sl_error err;
        if (sl_pk3_list_maps(g.gl_pathv[k], sl_test_collect_name, &list, &err) != SL_OK)
            fail_msg("%s", err.message);
        for (int i = 0; i < list.count; i++) {
            if (sanitized && seen++ % 8)
                continue;
            maps++;
            sl_scene s;
            if (sl_import_q3bsp(g.gl_pathv[k], list.names[i], NULL, NULL, &s, &err) != SL_OK)
                fail_msg("%s: %s", list.names[i], err.message);
            loaded++;
            unsigned spawns = (unsigned)atoi(sl_scene_meta(s, "q3.spawn_count"));
            sl_path p;
            sl_status st = sl_path_random_views(s, SL_VIEWS_STREET, 8, 1, NULL, NULL, &p, &err);
            if (st == SL_OK) {
                with_views++;
                sl_path_destroy(p);
            } else if (spawns || !strstr(list.names[i], "_init")) {
                /* only maps/_init/_init (the menu's background map) has no spawn point */
                fail_msg("%s: %u spawn points and no street views: %s", list.names[i], spawns, err.message);
            }
            print_message("%-32s %3u spawns %s\n", list.names[i], spawns, st == SL_OK ? "views" : "no views");
            sl_scene_destroy(s);
        }
    }
    globfree(&g);
    print_message("nexuiz: %u maps, %u loaded, %u with street views\n", maps, loaded, with_views);
    assert_true(maps > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tiny_map),          cmocka_unit_test(test_node_renumbering),
        cmocka_unit_test(test_model_leaf),
        cmocka_unit_test(test_tiny_hostile),      cmocka_unit_test(test_pk3),
        cmocka_unit_test(test_openarena_maps),    cmocka_unit_test(test_openarena_pvs),
        cmocka_unit_test(test_openarena_split),
        cmocka_unit_test(test_openarena_hostile),
        cmocka_unit_test(test_spawn_classes),     cmocka_unit_test(test_patch_expansion),
        cmocka_unit_test(test_bsp_boxes),
        cmocka_unit_test(test_pk3_names),         cmocka_unit_test(test_nexuiz_maps),
        cmocka_unit_test(test_pk3_escaped_names),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

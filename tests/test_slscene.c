/* The .slscene reader and writer: round trips of a scene that uses every section (mapped, read,
 * copied from memory), determinism of the writer, mutation of a mapped scene, and hostile files:
 * truncation at every length, every single flipped byte, and structural lies with fixed-up
 * checksums so that the structural checks, not the checksums, must catch them.
 *
 * The byte offsets used below are the documented layout (docs/slscene-format.md), written out
 * again here on purpose: the test pins the format independently of the implementation. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "scene/scene_internal.h"
#include "sightline/slscene.h"
#include "support/counting_alloc.h"

/* ---- the documented layout ---- */
enum { HDR = 64, ENTRY = 48 };
enum { H_MAJOR = 8, H_MINOR = 12, H_FLAGS = 16, H_COUNT = 24, H_TABLE = 32, H_FILE_SIZE = 40, H_TABLE_HASH = 48, H_HASH = 56 };
enum { E_ELEM = 4, E_COUNT = 8, E_OFFSET = 16, E_SIZE = 24, E_HASH = 32 };

static uint32_t get32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t get64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static void put32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static void put64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

/* Byte position of the table entry of section `tag`, or 0 when absent. */
static size_t entry_of(const uint8_t *f, const char *tag)
{
    uint32_t n = get32(f + H_COUNT);
    uint64_t t = get64(f + H_TABLE);
    for (uint32_t i = 0; i < n; i++)
        if (memcmp(f + t + (size_t)i * ENTRY, tag, 4) == 0)
            return (size_t)(t + (size_t)i * ENTRY);
    return 0;
}

/* Pointer to the data of section `tag`. */
static uint8_t *section(uint8_t *f, const char *tag)
{
    size_t e = entry_of(f, tag);
    assert_true(e != 0);
    return f + get64(f + e + E_OFFSET);
}

/* Recompute every checksum (sections, table, header) after a deliberate edit of a file of n
 * bytes; parts that the edit moved outside the file are left alone. */
static void fix_checksums_n(uint8_t *f, size_t size)
{
    uint32_t n = get32(f + H_COUNT);
    uint64_t t = get64(f + H_TABLE);
    if (t <= size && (uint64_t)n * ENTRY <= size - t) {
        for (uint32_t i = 0; i < n; i++) {
            uint8_t *e = f + t + (size_t)i * ENTRY;
            uint64_t off = get64(e + E_OFFSET), len = get64(e + E_SIZE);
            if (off <= size && len <= size - off)
                put64(e + E_HASH, sl_hash64(f + off, len, 0));
        }
        put64(f + H_TABLE_HASH, sl_hash64(f + t, (size_t)n * ENTRY, 0));
    }
    put64(f + H_HASH, sl_hash64(f, H_HASH, 0));
}
#define fix_checksums(f) fix_checksums_n(f, fx->size)

/* ---- the scene every round trip uses ---- */

static const float k_box_p[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
static const uint32_t k_box_i[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                   1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};

static sl_affine translate(float x, float y, float z)
{
    sl_affine t = sl_affine_identity();
    t.m[3] = x, t.m[7] = y, t.m[11] = z;
    return t;
}

#define OK(call)                                                                                                      \
    do {                                                                                                              \
        sl_error e_;                                                                                                  \
        sl_status st_ = (call);                                                                                       \
        if (st_ != SL_OK)                                                                                             \
            fail_msg("%s failed: %s", #call, e_.message);                                                            \
    } while (0)
#define E (&e_)

static sl_scene build_full(const sl_allocator *a)
{
    sl_scene s;
    OK(sl_scene_create(a, &s, E));
    uint32_t box, quad, empty;
    sl_mesh_desc md = {k_box_p, NULL, 8, k_box_i, 12, NULL}; /* normals computed */
    OK(sl_scene_add_mesh(s, &md, &box, E));
    static const float qp[] = {-2, -2, 0, 2, -2, 0, 2, 2, 0, -2, 2, 0};
    static const float qn[] = {0, 0, 1, 0, 0, 1, 0, 0.6f, 0.8f, 0, 0, 1};
    static const uint32_t qi[] = {0, 1, 2, 0, 2, 3};
    sl_mesh_desc qd = {qp, qn, 4, qi, 2, NULL};
    OK(sl_scene_add_mesh(s, &qd, &quad, E));
    sl_mesh_desc ed = {NULL, NULL, 0, NULL, 0, NULL};
    OK(sl_scene_add_mesh(s, &ed, &empty, E));

    sl_affine t1 = translate(10, 0, 0);
    sl_affine rot = {{0, -1, 0, 20, 1, 0, 0, 5, 0, 0, 2, 0}}; /* 90 degrees about z, stretched in z */
    sl_object_desc od[] = {
        {box, NULL, 0xff0000ffu, SL_KIND_BUILDING, SL_OBJECT_CLOSED_CONVEX | SL_OBJECT_OCCLUDER, 0},
        {box, &t1, 0x00ff00ffu, SL_KIND_BUILDING, 0, 0},
        {box, &rot, 0x0000ffffu, SL_KIND_TREE, 0, 0},
        {box, NULL, 0x808080ffu, SL_KIND_CAR, SL_OBJECT_DYNAMIC, 0}, /* gets a transform slot */
        {quad, NULL, 0x202020ffu, SL_KIND_GROUND, 0, 0},
        {empty, &t1, 0, SL_KIND_OTHER, 0, 0},
    };
    for (size_t i = 0; i < SL_COUNTOF(od); i++)
        OK(sl_scene_add_object(s, &od[i], NULL, E));

    static const float fp0[] = {0, 0, 1, 0, 1, 1, 0, 1};
    static const float fp1[] = {10, 0, 10, 3, 12, 4, 13, 1, 11, -1}; /* clockwise: stored reversed */
    sl_footprint_desc fd0 = {fp0, 4, 0, 1, 0}, fd1 = {fp1, 5, 0.5f, 7.25f, SL_NONE};
    OK(sl_scene_add_footprint(s, &fd0, NULL, E));
    OK(sl_scene_add_footprint(s, &fd1, NULL, E));
    OK(sl_scene_add_occluder(s, box, NULL, 0, E));
    sl_affine t2 = translate(-3, 4, 0.5f);
    OK(sl_scene_add_occluder(s, box, &t2, 1, E));

    float heights[12];
    for (int i = 0; i < 12; i++)
        heights[i] = 0.25f * (float)i - 1.0f;
    sl_terrain_desc td = {4, 3, -5, -5, 2.5f, heights};
    OK(sl_scene_set_terrain(s, &td, E));

    static const float sp0[] = {-1, -1, 30, -1, 30, 1, -1, 1};
    static const float sp1[] = {0, 0, 0, 5, 5, 0}; /* clockwise */
    OK(sl_scene_add_street_polygon(s, sp0, 4, E));
    OK(sl_scene_add_street_polygon(s, sp1, 3, E));
    static const sl_street_node nodes[] = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
    static const sl_street_edge edges[] = {{0, 1, 6, SL_STREET_AVENUE}, {1, 2, 4, 0}, {2, 3, 3.5f, SL_STREET_BRIDGE}};
    OK(sl_scene_set_street_graph(s, nodes, 4, edges, 3, E));

    static const sl_plane planes[] = {{1, 0, 0, -5}, {0, 1, 0, -5}};
    sl_bsp_node bn[2] = {{0, {1, -1}, {{-10, -10, -10}, {10, 10, 10}}}, {1, {-2, -3}, {{-10, -10, -10}, {5, 10, 10}}}};
    sl_bsp_leaf bl[3] = {{0, 0, {{5, -10, -10}, {10, 10, 10}}, 0, 2},
                         {1, 0, {{-10, 5, -10}, {5, 10, 10}}, 2, 1},
                         {-1, 1, {{-10, -10, -10}, {5, 5, 10}}, 3, 1}};
    static const uint32_t lo[] = {0, 1, 2, 3};
    static const uint8_t pvs[] = {0x03, 0x02};
    sl_bsp_desc bd = {planes, 2, bn, 2, bl, 3, lo, 4, 2, 1, pvs};
    OK(sl_scene_set_bsp(s, &bd, E));

    OK(sl_scene_set_meta(s, "generator", "test_slscene", E));
    OK(sl_scene_set_meta(s, "empty", "", E));
    OK(sl_scene_set_meta(s, "place", "Wien \xe2\x80\x93 Innere Stadt", E));
    return s;
}

static void assert_same_floats(const float *a, const float *b, size_t n)
{
    if (n)
        assert_memory_equal(a, b, n * sizeof(float));
}

/* Every accessor of the public API answers the same, bit for bit. */
static void assert_same_scene(sl_scene a, sl_scene b)
{
    assert_int_equal(sl_scene_mesh_count(a), sl_scene_mesh_count(b));
    for (uint32_t i = 0; i < sl_scene_mesh_count(a); i++) {
        sl_mesh_view x = sl_scene_mesh(a, i), y = sl_scene_mesh(b, i);
        assert_int_equal(x.vertex_count, y.vertex_count);
        assert_int_equal(x.triangle_count, y.triangle_count);
        assert_same_floats(x.positions, y.positions, 3 * (size_t)x.vertex_count);
        assert_same_floats(x.normals, y.normals, 3 * (size_t)x.vertex_count);
        if (x.triangle_count)
            assert_memory_equal(x.indices, y.indices, 3 * sizeof(uint32_t) * x.triangle_count);
        assert_memory_equal(&x.bounds, &y.bounds, sizeof x.bounds);
    }
    assert_int_equal(sl_scene_object_count(a), sl_scene_object_count(b));
    for (uint32_t i = 0; i < sl_scene_object_count(a); i++) {
        sl_object_view x = sl_scene_object(a, i), y = sl_scene_object(b, i);
        assert_int_equal(x.mesh, y.mesh);
        assert_int_equal(x.color, y.color);
        assert_int_equal(x.kind, y.kind);
        assert_int_equal(x.flags, y.flags);
        assert_int_equal(x.identity, y.identity);
        assert_int_equal(x.triangle_count, y.triangle_count);
        assert_memory_equal(&x.transform, &y.transform, sizeof x.transform);
        assert_memory_equal(&x.bounds, &y.bounds, sizeof x.bounds);
        sl_aabb ba = sl_scene_object_bounds(a, i), bb = sl_scene_object_bounds(b, i);
        assert_memory_equal(&ba, &bb, sizeof ba);
    }
    if (sl_scene_object_count(a))
        assert_memory_equal(sl_scene_object_bounds_array(a), sl_scene_object_bounds_array(b),
                            sl_scene_object_count(a) * sizeof(sl_aabb));
    assert_int_equal(sl_scene_footprint_count(a), sl_scene_footprint_count(b));
    for (uint32_t i = 0; i < sl_scene_footprint_count(a); i++) {
        sl_footprint_view x = sl_scene_footprint(a, i), y = sl_scene_footprint(b, i);
        assert_int_equal(x.vertex_count, y.vertex_count);
        assert_same_floats(x.xy, y.xy, 2 * (size_t)x.vertex_count);
        assert_true(x.base_z == y.base_z && x.roof_z == y.roof_z);
        assert_int_equal(x.object, y.object);
    }
    assert_int_equal(sl_scene_occluder_count(a), sl_scene_occluder_count(b));
    for (uint32_t i = 0; i < sl_scene_occluder_count(a); i++) {
        sl_occluder_view x = sl_scene_occluder(a, i), y = sl_scene_occluder(b, i);
        assert_int_equal(x.mesh, y.mesh);
        assert_int_equal(x.object, y.object);
        assert_memory_equal(&x.transform, &y.transform, sizeof x.transform);
    }
    sl_terrain_view ta, tb;
    bool ha = sl_scene_terrain(a, &ta), hb = sl_scene_terrain(b, &tb);
    assert_int_equal(ha, hb);
    if (ha) {
        assert_true(ta.nx == tb.nx && ta.ny == tb.ny && ta.origin_x == tb.origin_x && ta.origin_y == tb.origin_y &&
                    ta.cell == tb.cell);
        assert_same_floats(ta.heights, tb.heights, (size_t)ta.nx * ta.ny);
        for (float x = -6; x < 6; x += 0.7f)
            assert_true(sl_scene_ground_height(a, x, 0.3f * x) == sl_scene_ground_height(b, x, 0.3f * x));
    }
    assert_int_equal(sl_scene_street_polygon_count(a), sl_scene_street_polygon_count(b));
    for (uint32_t i = 0; i < sl_scene_street_polygon_count(a); i++) {
        sl_polygon_view x = sl_scene_street_polygon(a, i), y = sl_scene_street_polygon(b, i);
        assert_int_equal(x.vertex_count, y.vertex_count);
        assert_same_floats(x.xy, y.xy, 2 * (size_t)x.vertex_count);
    }
    const sl_street_node *na, *nb;
    const sl_street_edge *ea, *eb;
    uint32_t nna, nnb, nea, neb;
    sl_scene_street_graph(a, &na, &nna, &ea, &nea);
    sl_scene_street_graph(b, &nb, &nnb, &eb, &neb);
    assert_int_equal(nna, nnb);
    assert_int_equal(nea, neb);
    if (nna)
        assert_memory_equal(na, nb, nna * sizeof *na);
    if (nea)
        assert_memory_equal(ea, eb, nea * sizeof *ea);
    sl_bsp_view va, vb;
    ha = sl_scene_bsp(a, &va), hb = sl_scene_bsp(b, &vb);
    assert_int_equal(ha, hb);
    if (ha) {
        assert_int_equal(va.plane_count, vb.plane_count);
        assert_int_equal(va.node_count, vb.node_count);
        assert_int_equal(va.leaf_count, vb.leaf_count);
        assert_int_equal(va.leaf_object_count, vb.leaf_object_count);
        assert_int_equal(va.cluster_count, vb.cluster_count);
        assert_int_equal(va.cluster_bytes, vb.cluster_bytes);
        if (va.plane_count)
            assert_memory_equal(va.planes, vb.planes, va.plane_count * sizeof(sl_plane));
        if (va.node_count)
            assert_memory_equal(va.nodes, vb.nodes, va.node_count * sizeof(sl_bsp_node));
        if (va.leaf_count)
            assert_memory_equal(va.leaves, vb.leaves, va.leaf_count * sizeof(sl_bsp_leaf));
        if (va.leaf_object_count)
            assert_memory_equal(va.leaf_objects, vb.leaf_objects, va.leaf_object_count * sizeof(uint32_t));
        assert_int_equal(va.pvs == NULL, vb.pvs == NULL);
        if (va.pvs)
            assert_memory_equal(va.pvs, vb.pvs, (size_t)va.cluster_count * va.cluster_bytes);
        for (float x = -9; x < 10; x += 1.5f)
            assert_int_equal(sl_scene_bsp_find_leaf(a, (sl_vec3){x, 9 - x, 0}),
                             sl_scene_bsp_find_leaf(b, (sl_vec3){x, 9 - x, 0}));
    }
    assert_int_equal(sl_scene_meta_count(a), sl_scene_meta_count(b));
    for (uint32_t i = 0; i < sl_scene_meta_count(a); i++) {
        const char *ka, *xa, *kb, *xb;
        sl_scene_meta_at(a, i, &ka, &xa);
        sl_scene_meta_at(b, i, &kb, &xb);
        assert_string_equal(ka, kb);
        assert_string_equal(xa, xb);
        assert_string_equal(sl_scene_meta(b, ka), xa);
    }
    sl_scene_stats sa, sb;
    sl_scene_get_stats(a, &sa);
    sl_scene_get_stats(b, &sb);
    sa.memory_bytes = sb.memory_bytes = 0; /* mapped and built scenes hold memory differently */
    assert_memory_equal(&sa, &sb, sizeof sa);
}

/* ---- fixture: a temporary directory and the full scene's bytes ---- */

typedef struct fixture {
    char dir[64];
    char path[128];
    uint8_t *bytes;
    size_t size;
} fixture;

static void join(char *out, size_t n, const fixture *fx, const char *name) { snprintf(out, n, "%s/%s", fx->dir, name); }

static int setup(void **state)
{
    fixture *fx = calloc(1, sizeof *fx);
    snprintf(fx->dir, sizeof fx->dir, "/tmp/sl_slscene_XXXXXX");
    if (!mkdtemp(fx->dir))
        return -1;
    join(fx->path, sizeof fx->path, fx, "full.slscene");
    sl_scene s = build_full(NULL);
    sl_error err;
    if (sl_scene_save(s, fx->path, &err) != SL_OK || sl_file_read_all(NULL, fx->path, &fx->bytes, &fx->size, &err))
        return -1;
    sl_scene_destroy(s);
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fixture *fx = *state;
    DIR *d = opendir(fx->dir);
    struct dirent *e;
    char p[512];
    while (d && (e = readdir(d)))
        if (e->d_name[0] != '.') {
            snprintf(p, sizeof p, "%s/%s", fx->dir, e->d_name);
            unlink(p);
        }
    if (d)
        closedir(d);
    rmdir(fx->dir);
    sl_free(NULL, fx->bytes, fx->size);
    free(fx);
    return 0;
}

static int count_files(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += e->d_name[0] != '.';
    if (d)
        closedir(d);
    return n;
}

static bool same_file(const char *a, const char *b)
{
    uint8_t *x, *y;
    size_t nx, ny;
    sl_error err;
    assert_int_equal(sl_file_read_all(NULL, a, &x, &nx, &err), SL_OK);
    assert_int_equal(sl_file_read_all(NULL, b, &y, &ny, &err), SL_OK);
    bool same = nx == ny && memcmp(x, y, nx) == 0;
    sl_free(NULL, x, nx);
    sl_free(NULL, y, ny);
    return same;
}

static void write_file(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* Number of lines of /proc/self/maps: a leaked mapping would show up here. */
static int mapping_count(void)
{
    FILE *f = fopen("/proc/self/maps", "r");
    if (!f)
        return -1;
    int n = 0, c;
    while ((c = fgetc(f)) != EOF)
        n += c == '\n';
    fclose(f);
    return n;
}

/* ---- round trips ---- */

static void test_round_trip(void **state)
{
    fixture *fx = *state;
    sl_scene ref = build_full(NULL);
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_load_options modes[3];
    memset(modes, 0, sizeof modes);
    modes[0].map = true;  /* mapped; modes[1]: the default, read */
    modes[2].map = true;
    modes[2].skip_checksums = true;
    for (int m = 0; m < 3; m++) {
        sl_scene s;
        OK(sl_scene_load(fx->path, &modes[m], &a, &s, E));
        assert_same_scene(ref, s);
        /* mapped bulk arrays are borrowed, records that move are owned */
        assert_int_equal(s->positions.cap == 0, modes[m].map);
        assert_true(s->objects.cap > 0 && s->transforms.cap > 0 && s->bounds.cap > 0);
        assert_int_equal(s->mapping.data != NULL, modes[m].map);
        /* saving a loaded scene reproduces the file byte for byte */
        char again[256];
        join(again, sizeof again, fx, "again.slscene");
        OK(sl_scene_save(s, again, E));
        assert_true(same_file(fx->path, again));
        sl_scene_destroy(s);
        assert_int_equal(c.live, 0);
    }
    sl_scene s;
    OK(sl_scene_load_memory(fx->bytes, fx->size, "full", &a, &s, E));
    assert_same_scene(ref, s);
    sl_scene_destroy(s);
    assert_int_equal(c.live, 0);
    /* the generic opener dispatches on the extension, case-insensitively */
    OK(sl_scene_open(fx->path, NULL, &a, &s, E));
    assert_same_scene(ref, s);
    sl_scene_destroy(s);
    char upper[256];
    join(upper, sizeof upper, fx, "UPPER.SLSCENE");
    write_file(upper, fx->bytes, fx->size);
    OK(sl_scene_open(upper, NULL, &a, &s, E));
    sl_scene_destroy(s);
    sl_error err;
    assert_int_equal(sl_scene_open(fx->path, "oa_dm1", &a, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(s);
    assert_non_null(strstr(err.message, ".pk3"));
    assert_int_equal(c.live, 0);
    sl_scene_destroy(ref);
}

static void test_deterministic(void **state)
{
    fixture *fx = *state;
    char p1[256], p2[256];
    join(p1, sizeof p1, fx, "det1.slscene");
    join(p2, sizeof p2, fx, "det2.slscene");
    sl_scene a = build_full(NULL), b = build_full(NULL);
    OK(sl_scene_save(a, p1, E));
    OK(sl_scene_save(a, p2, E));
    assert_true(same_file(p1, p2));
    OK(sl_scene_save(b, p2, E)); /* a second, separately built scene */
    assert_true(same_file(p1, p2));
    assert_true(same_file(p1, fx->path));
    sl_scene_destroy(a);
    sl_scene_destroy(b);
    /* every gap between sections is zero and every section is aligned */
    const uint8_t *f = fx->bytes;
    assert_memory_equal(f, "SLSCENE\0", 8);
    assert_int_equal(get32(f + H_MAJOR), 1);
    assert_int_equal(get32(f + H_MINOR), 1);
    assert_int_equal(get32(f + H_FLAGS), 3); /* terrain and bsp */
    assert_int_equal(get64(f + H_FILE_SIZE), fx->size);
    assert_int_equal(fx->size % 64, 0);
    uint32_t n = get32(f + H_COUNT);
    assert_int_equal(n, 30); /* 23 of format 1.0, seven of 1.1 (materials, uvs, object names) */
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *e = f + HDR + (size_t)i * ENTRY;
        assert_int_equal(get64(e + E_OFFSET) % 64, 0);
        assert_int_equal(get64(e + E_COUNT) * get32(e + E_ELEM), get64(e + E_SIZE));
    }
    /* an empty scene round-trips too */
    sl_scene empty, back;
    OK(sl_scene_create(NULL, &empty, E));
    OK(sl_scene_save(empty, p1, E));
    OK(sl_scene_load(p1, NULL, NULL, &back, E));
    assert_same_scene(empty, back);
    sl_scene_destroy(back);
    sl_scene_destroy(empty);
}

/* Apply the same edits to a scene, loaded or built. */
static void edit(sl_scene s)
{
    sl_affine moved = translate(3, 2, 1);
    OK(sl_scene_set_object_transform(s, 3, &moved, E)); /* the dynamic car */
    OK(sl_scene_set_object_transform(s, 0, &moved, E)); /* an object without a transform slot */
    static const float tp[] = {0, 0, 5, 1, 0, 5, 0, 1, 5};
    static const uint32_t ti[] = {0, 1, 2};
    sl_mesh_desc md = {tp, NULL, 3, ti, 1, NULL};
    uint32_t mesh;
    OK(sl_scene_add_mesh(s, &md, &mesh, E));
    sl_object_desc od = {mesh, NULL, 7, SL_KIND_LAMP, 0, 0};
    OK(sl_scene_add_object(s, &od, NULL, E));
    static const float fp[] = {50, 50, 52, 50, 51, 52};
    sl_footprint_desc fd = {fp, 3, 0, 3, SL_NONE};
    OK(sl_scene_add_footprint(s, &fd, NULL, E));
    OK(sl_scene_set_meta(s, "generator", "edited", E));
}

static void test_mutate_loaded(void **state)
{
    fixture *fx = *state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_scene s, ref = build_full(NULL);
    sl_load_options mapped = {.map = true};
    OK(sl_scene_load(fx->path, &mapped, &a, &s, E));
    assert_int_equal(s->positions.cap, 0);
    assert_int_equal(s->footprints.cap, 0);
    sl_aabb before = sl_scene_object_bounds(s, 3);
    edit(s);
    edit(ref);
    sl_aabb after = sl_scene_object_bounds(s, 3);
    assert_true(after.min.x == before.min.x + 3 && after.min.z == before.min.z + 1);
    /* the arrays that grew are owned copies now, and the old meshes are intact */
    assert_true(s->positions.cap > 0 && s->indices.cap > 0 && s->footprints.cap > 0);
    assert_same_scene(ref, s);
    char p[256];
    join(p, sizeof p, fx, "edited.slscene");
    OK(sl_scene_save(s, p, E));
    sl_scene back;
    OK(sl_scene_load(p, NULL, &a, &back, E));
    assert_same_scene(ref, back);
    sl_scene_destroy(back);
    sl_scene_destroy(s);
    sl_scene_destroy(ref);
    assert_int_equal(c.live, 0);
}

/* Saving a mapped scene over its own file: the new file is renamed into place, the old inode
 * stays mapped, so the scene remains readable and the result is the same bytes. */
static void test_save_over_own_mapping(void **state)
{
    fixture *fx = *state;
    char p[256];
    join(p, sizeof p, fx, "self.slscene");
    write_file(p, fx->bytes, fx->size);
    sl_scene s, ref = build_full(NULL);
    sl_load_options mapped = {.map = true};
    OK(sl_scene_load(p, &mapped, NULL, &s, E));
    OK(sl_scene_save(s, p, E));
    assert_same_scene(ref, s);
    assert_true(same_file(p, fx->path));
    edit(s);
    OK(sl_scene_save(s, p, E));
    sl_scene back;
    OK(sl_scene_load(p, NULL, NULL, &back, E));
    edit(ref);
    assert_same_scene(ref, back);
    sl_scene_destroy(back);
    sl_scene_destroy(s);
    sl_scene_destroy(ref);
}

/* sl_scene_open hands other extensions to the importers. */
static void test_open_dispatch(void **state)
{
    fixture *fx = *state;
    char p[256];
    join(p, sizeof p, fx, "tri.obj");
    static const char obj[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    write_file(p, obj, sizeof obj - 1);
    sl_scene s;
    OK(sl_scene_open(p, NULL, NULL, &s, E));
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    assert_int_equal(st.triangle_count, 1);
    sl_scene_destroy(s);
    sl_error err;
    assert_int_equal(sl_scene_open(p, "map", NULL, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    static const char *missing[] = {"missing.bsp", "missing.pk3", "missing.glb", "missing.slscene"};
    for (size_t i = 0; i < SL_COUNTOF(missing); i++) {
        join(p, sizeof p, fx, missing[i]);
        s = (sl_scene)1;
        assert_int_not_equal(sl_scene_open(p, i == 1 ? "oa_dm1" : NULL, NULL, &s, &err), SL_OK);
        assert_null(s);
        assert_non_null(strstr(err.message, missing[i]));
    }
}

static bool cancel_second(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)stage, (void)done, (void)total;
    return ++*(int *)user < 2;
}

static void test_cancel_and_io_errors(void **state)
{
    fixture *fx = *state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    int calls = 0;
    sl_load_options opt;
    memset(&opt, 0, sizeof opt);
    opt.progress.fn = cancel_second;
    opt.progress.user = &calls;
    sl_scene s = NULL;
    sl_error err;
    assert_int_equal(sl_scene_load(fx->path, &opt, &a, &s, &err), SL_ERROR_CANCELLED);
    assert_null(s);
    assert_int_equal(c.live, 0);
    char p[256];
    join(p, sizeof p, fx, "missing.slscene");
    assert_int_equal(sl_scene_load(p, NULL, &a, &s, &err), SL_ERROR_NOT_FOUND);
    opt.no_mmap = true;
    opt.progress.fn = NULL;
    assert_int_equal(sl_scene_load(p, &opt, &a, &s, &err), SL_ERROR_NOT_FOUND);
    join(p, sizeof p, fx, "empty.slscene");
    write_file(p, "", 0);
    assert_int_equal(sl_scene_load(p, NULL, &a, &s, &err), SL_ERROR_FORMAT);
    assert_int_equal(sl_scene_load(p, &opt, &a, &s, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "empty.slscene"));
    assert_int_equal(sl_scene_load(fx->dir, &opt, &a, &s, &err), SL_ERROR_IO); /* a directory */
    assert_int_equal(c.live, 0);
}

/* No partial or temporary file is left when the output cannot be written. */
static void test_save_failure_leaves_nothing(void **state)
{
    fixture *fx = *state;
    sl_scene s = build_full(NULL);
    sl_error err;
    char sub[256], p[300];
    join(sub, sizeof sub, fx, "sub");
    assert_int_equal(mkdir(sub, 0755), 0);
    /* the target is a directory: everything is written, then the rename fails */
    snprintf(p, sizeof p, "%s/target.slscene", sub);
    assert_int_equal(mkdir(p, 0755), 0);
    assert_int_equal(sl_scene_save(s, p, &err), SL_ERROR_IO);
    assert_non_null(strstr(err.message, "target.slscene"));
    assert_int_equal(count_files(sub), 1);
    rmdir(p);
    /* a directory that does not exist */
    snprintf(p, sizeof p, "%s/nowhere/x.slscene", sub);
    assert_int_equal(sl_scene_save(s, p, &err), SL_ERROR_IO);
    /* a read-only directory (root ignores permissions, so only as another user) */
    if (geteuid() != 0) {
        assert_int_equal(chmod(sub, 0555), 0);
        snprintf(p, sizeof p, "%s/ro.slscene", sub);
        assert_int_equal(sl_scene_save(s, p, &err), SL_ERROR_IO);
        assert_int_equal(chmod(sub, 0755), 0);
    }
    assert_int_equal(count_files(sub), 0);
    rmdir(sub);
    sl_scene_destroy(s);
}

/* ---- hostile files ---- */

/* Loading `f` fails with `status` and a message naming `name` and containing `want` (if any),
 * through memory and through a file (mapped and read), without leaking. */
static void expect_fail_ex(const fixture *fx, const uint8_t *f, size_t n, sl_status status, const char *want, bool files)
{
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_scene s = (sl_scene)1;
    sl_error err;
    sl_status st = sl_scene_load_memory(f, n, "hostile.slscene", &a, &s, &err);
    if (st != status || (want && !strstr(err.message, want)))
        fail_msg("expected status %d with \"%s\", got %d: %s", status, want ? want : "", st, err.message);
    assert_null(s);
    assert_non_null(strstr(err.message, "hostile.slscene"));
    assert_int_equal(c.live, 0);
    if (!files)
        return;
    char p[256];
    join(p, sizeof p, fx, "hostile.slscene");
    write_file(p, f, n);
    sl_load_options opt;
    memset(&opt, 0, sizeof opt);
    for (int m = 0; m < 2; m++) {
        opt.map = m == 0;
        st = sl_scene_load(p, &opt, &a, &s, &err);
        if (st != status || (want && !strstr(err.message, want)))
            fail_msg("file (map=%d): expected %d with \"%s\", got %d: %s", m, status, want ? want : "", st,
                     err.message);
        assert_non_null(strstr(err.message, "hostile.slscene"));
        assert_int_equal(c.live, 0);
    }
}
static void expect_fail(const fixture *fx, const uint8_t *f, size_t n, sl_status status, const char *want)
{
    expect_fail_ex(fx, f, n, status, want, true);
}

static uint8_t *copy_of(const fixture *fx)
{
    uint8_t *f = malloc(fx->size);
    memcpy(f, fx->bytes, fx->size);
    return f;
}

static void test_truncated(void **state)
{
    fixture *fx = *state;
    int maps = mapping_count();
    for (size_t n = 0; n < fx->size; n++)
        expect_fail_ex(fx, fx->bytes, n, SL_ERROR_FORMAT, NULL, n % 97 == 0 || n < 70);
    /* the header notices a truncated file before anything else is read */
    expect_fail(fx, fx->bytes, fx->size - 64, SL_ERROR_FORMAT, "offset 40");
    expect_fail(fx, fx->bytes, 10, SL_ERROR_FORMAT, "shorter than the 64-byte header");
    /* bytes appended to a valid file are refused as well */
    uint8_t *f = malloc(fx->size + 64);
    memcpy(f, fx->bytes, fx->size);
    memset(f + fx->size, 0, 64);
    expect_fail(fx, f, fx->size + 64, SL_ERROR_FORMAT, "appended");
    free(f);
    assert_int_equal(mapping_count(), maps);
}

static void test_every_flipped_byte(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    for (size_t i = 0; i < fx->size; i++) {
        for (int b = 0; b < 8; b += 7) {
            f[i] ^= (uint8_t)(1u << b);
            sl_scene s = NULL;
            sl_error err;
            sl_status st = sl_scene_load_memory(f, fx->size, "flip", NULL, &s, &err);
            if (st != SL_ERROR_FORMAT && st != SL_ERROR_UNSUPPORTED)
                fail_msg("flipping bit %d of byte %zu was not noticed (status %d)", b, i, st);
            f[i] ^= (uint8_t)(1u << b);
        }
    }
    /* a flip inside each non-empty section is a checksum error naming the section */
    uint32_t n = get32(f + H_COUNT);
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *e = fx->bytes + HDR + (size_t)i * ENTRY;
        uint64_t off = get64(e + E_OFFSET), size = get64(e + E_SIZE);
        if (!size)
            continue;
        char want[64];
        snprintf(want, sizeof want, "section '%.4s' at offset %llu: checksum mismatch", (const char *)e,
                 (unsigned long long)off);
        f[off + size / 2] ^= 0x10;
        expect_fail_ex(fx, f, fx->size, SL_ERROR_FORMAT, want, i % 4 == 0);
        f[off + size / 2] ^= 0x10;
    }
    /* with checksums skipped, structure is still validated: a flipped index is out of range */
    sl_load_options opt;
    memset(&opt, 0, sizeof opt);
    opt.skip_checksums = true;
    uint8_t *idx = section(f, "VIDX");
    idx[4 * 5 + 1] ^= 0x40; /* index 5 becomes >= 16384 */
    char p[256];
    join(p, sizeof p, fx, "skip.slscene");
    write_file(p, f, fx->size);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_load(p, &opt, NULL, &s, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "mesh 0: triangle 1 has index"));
    free(f);
}

static void test_header_lies(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    memcpy(f, "SLSCENF", 7);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "offset 0: bad magic");
    memcpy(f, fx->bytes, fx->size);
    /* a newer major version is refused as unsupported, checksum fixed or not */
    put32(f + H_MAJOR, 2);
    put32(f + H_MINOR, 0);
    expect_fail(fx, f, fx->size, SL_ERROR_UNSUPPORTED, "version 2.0 is newer");
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_UNSUPPORTED, "upgrade");
    put32(f + H_MAJOR, 0);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "version 0");
    memcpy(f, fx->bytes, fx->size);
    put64(f + H_FILE_SIZE, fx->size + 64);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "header checksum mismatch");
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "offset 40: truncated: expected");
    memcpy(f, fx->bytes, fx->size);
    put64(f + H_TABLE, fx->size - 32);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "section table");
    memcpy(f, fx->bytes, fx->size);
    put32(f + H_COUNT, 0xfffffff0u);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "sections is more than");
    memcpy(f, fx->bytes, fx->size);
    put32(f + 20, 16); /* header size below 64 */
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "header size 16");
    memcpy(f, fx->bytes, fx->size);
    f[HDR + 10] ^= 1; /* table byte without a table checksum fix */
    put64(f + H_HASH, sl_hash64(f, H_HASH, 0));
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "section table checksum mismatch");
    /* clearing the terrain flag while the terrain sections are present */
    memcpy(f, fx->bytes, fx->size);
    put32(f + H_FLAGS, 2);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "no terrain flag");
    free(f);
}

static void test_table_lies(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    size_t vpos = entry_of(f, "VPOS"), vnrm = entry_of(f, "VNRM"), mesh = entry_of(f, "MESH");
    assert_true(vpos && vnrm && mesh);
    /* a section past the end of the file */
    put64(f + vpos + E_OFFSET, fx->size + 64 * 1000);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "section 'VPOS': 144 bytes at offset");
    /* a misaligned section */
    memcpy(f, fx->bytes, fx->size);
    put64(f + vpos + E_OFFSET, get64(f + vpos + E_OFFSET) + 4);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "not 64-byte aligned");
    /* two sections over the same bytes */
    memcpy(f, fx->bytes, fx->size);
    put64(f + vnrm + E_OFFSET, get64(f + vpos + E_OFFSET));
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "overlaps");
    /* a section over the table */
    memcpy(f, fx->bytes, fx->size);
    put64(f + vpos + E_OFFSET, 64);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "overlaps");
    /* a count whose byte size overflows 64 bits, and one that does not match the size */
    memcpy(f, fx->bytes, fx->size);
    put64(f + vpos + E_COUNT, (1ull << 62) + 24);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "elements of 4 bytes do not make 144 bytes");
    memcpy(f, fx->bytes, fx->size);
    put64(f + vpos + E_COUNT, 25);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "do not make");
    /* a wrong element size, consistent with the byte size */
    memcpy(f, fx->bytes, fx->size);
    put32(f + mesh + E_ELEM, 24);
    put64(f + mesh + E_COUNT, get64(f + mesh + E_COUNT) * 2);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "element size 24, expected 48");
    /* a duplicated section */
    memcpy(f, fx->bytes, fx->size);
    memcpy(f + vnrm, "VPOS", 4);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "appears twice");
    /* an unknown section in a file of this version, and a missing required one */
    memcpy(f, fx->bytes, fx->size);
    memcpy(f + mesh, "ZZZZ", 4);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "unknown section 'ZZZZ'");
    put32(f + H_MINOR, 7);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "section 'MESH' (meshes): required section is missing");
    /* a nonzero padding byte between sections */
    memcpy(f, fx->bytes, fx->size);
    uint64_t end = get64(f + mesh + E_OFFSET) + get64(f + mesh + E_SIZE);
    assert_true(end % 64 != 0);
    f[end] = 1;
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "padding byte is not zero");
    free(f);
}

/* Motion records (docs/motion.md): the API's checks, a round trip through .slscene 1.3 (MOTN), a
 * scene without records still written as before, and hostile records refused with the record and
 * the reason. */
static void test_motion_records(void **state)
{
    fixture *fx = *state;
    sl_scene s;
    OK(sl_scene_create(NULL, &s, E));
    uint32_t box;
    sl_mesh_desc md = {k_box_p, NULL, 8, k_box_i, 12, NULL};
    OK(sl_scene_add_mesh(s, &md, &box, E));
    sl_object_desc still = {box, NULL, 0, SL_KIND_OTHER, 0, 0};
    sl_affine at = translate(5, 0, 0);
    sl_object_desc moving = {box, &at, 0, SL_KIND_CAR, SL_OBJECT_DYNAMIC, 0};
    uint32_t o0, o1, o2;
    OK(sl_scene_add_object(s, &still, &o0, E));
    OK(sl_scene_add_object(s, &moving, &o1, E));
    OK(sl_scene_add_object(s, &moving, &o2, E));
    sl_error err;
    sl_object_motion parked = {.max_speed = 0, .region = {{4, -1, -1}, {7, 2, 2}}};
    sl_object_motion drive = {.max_speed = 10, .region = {{4.9f, -0.1f, -0.1f}, {26.1f, 1.1f, 1.1f}}, .has_path = true,
                              .path_base = at, .from = {0, 0, 0}, .to = {20, 0, 0}, .speed = 8, .phase = 30};
    /* the checks */
    assert_int_equal(sl_scene_set_object_motion(s, o0, &parked, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "DYNAMIC"));
    sl_object_motion bad = drive;
    bad.speed = 11;
    assert_int_equal(sl_scene_set_object_motion(s, o1, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "speed"));
    bad = drive;
    bad.to.x = 30; /* beyond its region */
    assert_int_equal(sl_scene_set_object_motion(s, o1, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "leaves its region"));
    bad = drive;
    bad.phase = 40;
    assert_int_equal(sl_scene_set_object_motion(s, o1, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    bad = parked;
    bad.max_speed = NAN;
    assert_int_equal(sl_scene_set_object_motion(s, o1, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_scene_motion_count(s), 0);
    /* out of order: kept ascending */
    OK(sl_scene_set_object_motion(s, o2, &parked, E));
    OK(sl_scene_set_object_motion(s, o1, &drive, E));
    assert_int_equal(sl_scene_motion_count(s), 2);
    assert_int_equal(sl_scene_path_count(s), 1);
    /* animation: phase 30 of a 20 m path is 10 m on the way back; t = 1.25 s adds 10 m: at from */
    OK(sl_scene_animate(s, 1.25, E));
    sl_aabb b = sl_scene_object_bounds(s, o1);
    assert_true(fabsf(b.min.x - 5) < 1e-4f && fabsf(b.max.x - 6) < 1e-4f);
    OK(sl_scene_animate(s, 0, E));
    b = sl_scene_object_bounds(s, o1);
    assert_true(fabsf(b.min.x - 15) < 1e-4f && fabsf(b.max.x - 16) < 1e-4f);
    /* the round trip */
    char path[256];
    join(path, sizeof path, fx, "motion.slscene");
    OK(sl_scene_save(s, path, E));
    sl_scene t;
    OK(sl_scene_load(path, NULL, NULL, &t, E));
    sl_object_motion m;
    assert_true(sl_scene_object_motion(t, o1, &m));
    assert_true(m.has_path && m.speed == 8 && m.phase == 30 && m.to.x == 20);
    assert_memory_equal(&m.path_base, &at, sizeof at);
    assert_true(sl_scene_object_motion(t, o2, &m) && !m.has_path && m.region.max.x == 7);
    assert_false(sl_scene_object_motion(t, o0, &m));
    sl_scene_destroy(t);
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    size_t n = (size_t)ftell(fp);
    rewind(fp);
    uint8_t *f = malloc(n), *g = malloc(n);
    assert_int_equal(fread(f, 1, n, fp), n);
    fclose(fp);
    assert_int_equal(get32(f + H_MINOR), 3);
    uint8_t *rec = f + get64(f + entry_of(f, "MOTN") + E_OFFSET);
    static const struct {
        size_t at;
        uint32_t value;
        const char *want;
    } lies[] = {
        {0, 7, "object 7 out of range"},                 /* record 0's object */
        {128, 1, "not strictly ascending"},              /* record 1's object = record 0's */
        {0, 0, "is not DYNAMIC"},                        /* object 0 */
        {4, 4, "unknown flag bits"},
        {20, 1, "reserved fields must be zero"},
        {8, 0x7fc00000u, "max_speed"},                   /* NaN */
        {12, 0x41300000u, "speed must be in"},           /* 11 > max_speed 10 */
        {60, 0x41f00000u, "leaves its region"},          /* to.x = 30 */
    };
    for (size_t k = 0; k < sizeof lies / sizeof lies[0]; k++) {
        memcpy(g, f, n);
        uint8_t *r = g + (rec - f);
        put32(r + lies[k].at, lies[k].value);
        fix_checksums_n(g, n);
        expect_fail_ex(fx, g, n, SL_ERROR_FORMAT, lies[k].want, false);
    }
    free(f);
    free(g);
    /* without records: the version it had before */
    OK(sl_scene_set_object_motion(s, o1, NULL, E));
    OK(sl_scene_set_object_motion(s, o2, NULL, E));
    OK(sl_scene_save(s, path, E));
    fp = fopen(path, "rb");
    uint8_t head[16];
    assert_int_equal(fread(head, 1, 16, fp), 16);
    fclose(fp);
    assert_int_equal(get32(head + H_MINOR), 1);
    sl_scene_destroy(s);
}

static void test_newer_minor_version(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    /* a section this reader does not know, from a newer minor version: skipped */
    memcpy(f + entry_of(f, "SEDG"), "XEDG", 4);
    put32(f + H_MINOR, 4);
    fix_checksums(f);
    sl_scene s;
    OK(sl_scene_load_memory(f, fx->size, "newer", NULL, &s, E));
    uint32_t nodes, edges;
    sl_scene_street_graph(s, NULL, &nodes, NULL, &edges);
    assert_int_equal(nodes, 4);
    assert_int_equal(edges, 0);
    sl_scene_destroy(s);
    free(f);
}

/* Edits inside sections with fixed-up checksums: the structural checks must catch each. */
static void test_content_lies(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    /* an index out of range */
    uint32_t *idx = (uint32_t *)section(f, "VIDX");
    idx[7] = 8;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "hostile.slscene: mesh 0: triangle 2 has index 8 >= 8 vertices");
    /* NaN in a position */
    memcpy(f, fx->bytes, fx->size);
    float *pos = (float *)section(f, "VPOS");
    pos[3 * 9 + 1] = NAN;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "vertex 9 (object ");
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "): position.y is NaN");
    /* infinity in a normal */
    memcpy(f, fx->bytes, fx->size);
    ((float *)section(f, "VNRM"))[2] = INFINITY;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "vertex 0 (object 0, mesh 0 vertex 0): normal.z is +inf");
    /* a mesh range past the vertex array */
    memcpy(f, fx->bytes, fx->size);
    sl_mesh_rec *m = (sl_mesh_rec *)section(f, "MESH");
    m[1].first_vertex = 1ull << 40;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "mesh 1: vertex or index range out of bounds");
    /* stored mesh bounds that do not contain the vertices */
    memcpy(f, fx->bytes, fx->size);
    m = (sl_mesh_rec *)section(f, "MESH");
    m[0].bounds.max.x = 0.5f;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "mesh 0: stored bounds do not contain its vertices");
    memcpy(f, fx->bytes, fx->size);
    m = (sl_mesh_rec *)section(f, "MESH");
    m[1].bounds.min.y = -INFINITY;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "mesh 1: bounds are not finite");
    /* an object on a mesh that does not exist, and a transform out of range */
    memcpy(f, fx->bytes, fx->size);
    sl_object_rec *o = (sl_object_rec *)section(f, "OBJS");
    o[2].mesh = 3;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "object 2: mesh 3 out of range");
    memcpy(f, fx->bytes, fx->size);
    o = (sl_object_rec *)section(f, "OBJS");
    o[1].transform = 99;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "object 1: transform 99 out of range");
    /* huge but finite mesh bounds overflow the world bounds of a stretched object */
    memcpy(f, fx->bytes, fx->size);
    m = (sl_mesh_rec *)section(f, "MESH");
    m[0].bounds.max.z = 3e38f;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "object 2: world bounds are not finite");
    /* a NaN transform */
    memcpy(f, fx->bytes, fx->size);
    ((float *)section(f, "XFRM"))[5] = NAN;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "transform 0: not finite");
    /* a clockwise footprint (mirrored in x) */
    memcpy(f, fx->bytes, fx->size);
    float *fxy = (float *)section(f, "FPXY");
    for (int i = 0; i < 4; i++)
        fxy[2 * i] = -fxy[2 * i];
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "footprint 0: polygon is not counter-clockwise");
    /* a footprint whose roof is below its base */
    memcpy(f, fx->bytes, fx->size);
    ((sl_footprint_rec *)section(f, "FOOT"))[1].roof_z = -1;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "footprint 1: bad heights");
    /* an occluder on a missing object */
    memcpy(f, fx->bytes, fx->size);
    ((sl_occluder_rec *)section(f, "OCCL"))[1].object = 77;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "occluder 1: reference out of range");
    /* terrain dimensions that do not match the heights */
    memcpy(f, fx->bytes, fx->size);
    put32(section(f, "TERH"), 5);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "terrain: bad dimensions");
    /* a street edge to a missing node, a negative width */
    memcpy(f, fx->bytes, fx->size);
    ((sl_street_edge *)section(f, "SEDG"))[2].b = 4;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "street edge 2: node out of range");
    memcpy(f, fx->bytes, fx->size);
    ((sl_street_edge *)section(f, "SEDG"))[0].width = -1;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "street edge 0: negative width");
    /* a NaN width is a NaN width, not a node out of range (issue 12) */
    memcpy(f, fx->bytes, fx->size);
    ((sl_street_edge *)section(f, "SEDG"))[1].width = NAN;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "street edge 1: width is NaN");
    /* NaN and infinite BSP node and leaf bounds (issue 12) */
    memcpy(f, fx->bytes, fx->size);
    ((sl_bsp_node *)section(f, "BNOD"))[1].bounds.min.x = NAN;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "bsp node 1: mins.x is NaN");
    memcpy(f, fx->bytes, fx->size);
    ((sl_bsp_leaf *)section(f, "BLEF"))[0].bounds.max.z = INFINITY;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "bsp leaf 0: maxs.z is infinite");
    /* a street polygon range past its vertices */
    memcpy(f, fx->bytes, fx->size);
    ((sl_polygon_rec *)section(f, "SPOL"))[1].vertex_count = 100;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "street polygon 1: vertex range out of bounds");
    /* a BSP child pointing backwards (traversal would loop), a cluster out of range */
    memcpy(f, fx->bytes, fx->size);
    ((sl_bsp_node *)section(f, "BNOD"))[1].children[0] = 0;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "bsp node 1: child 0 out of range");
    memcpy(f, fx->bytes, fx->size);
    ((sl_bsp_leaf *)section(f, "BLEF"))[0].cluster = 2;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "bsp leaf 0: cluster 2 out of range");
    /* more PVS rows than clusters */
    memcpy(f, fx->bytes, fx->size);
    put32(section(f, "BSPH"), 1);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "bsp vis");
    free(f);
}

static void test_metadata_lies(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    uint8_t *meta = section(f, "META");
    size_t e = entry_of(f, "META");
    uint64_t size = get64(f + e + E_SIZE);
    assert_int_equal(get32(meta), 3);
    assert_int_equal(get32(meta + 4), 9); /* "generator" */
    /* a key length past the end of the section */
    put32(meta + 4, 0x7fffffff);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "section 'META': entry 0: key of 2147483647 bytes");
    /* an entry count that cannot fit */
    memcpy(f, fx->bytes, fx->size);
    put32(meta, 1000000);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "1000000 entries cannot fit");
    /* fewer entries than stored: trailing bytes */
    memcpy(f, fx->bytes, fx->size);
    put32(meta, 2);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "trailing bytes");
    /* a NUL inside a key, an empty key, a duplicate key */
    memcpy(f, fx->bytes, fx->size);
    meta[8 + 3] = 0;
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "entry 0: key contains a NUL byte");
    memcpy(f, fx->bytes, fx->size);
    /* entry 1 ("empty" = ""): rename its key to "place" to clash with entry 2 */
    size_t k = 4 + 4 + 9 + 4 + 12; /* past entry 0 */
    assert_int_equal(get32(meta + k), 5);
    memcpy(meta + k + 4, "place", 5);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "duplicate key \"place\"");
    /* one entry with an empty key and a value filling the section */
    memcpy(f, fx->bytes, fx->size);
    put32(meta, 1);
    put32(meta + 4, 0);
    put32(meta + 8, (uint32_t)(size - 12));
    memset(meta + 12, 'x', size - 12);
    fix_checksums(f);
    expect_fail(fx, f, fx->size, SL_ERROR_FORMAT, "entry 0: empty key");
    free(f);
}

static void test_hostile_mappings_do_not_leak(void **state)
{
    fixture *fx = *state;
    uint8_t *f = copy_of(fx);
    ((uint32_t *)section(f, "VIDX"))[0] = 1000;
    fix_checksums(f);
    char p[256];
    join(p, sizeof p, fx, "leak.slscene");
    write_file(p, f, fx->size);
    int before = mapping_count();
    for (int i = 0; i < 50; i++) {
        sl_scene s;
        sl_error err;
        assert_int_equal(sl_scene_load(p, NULL, NULL, &s, &err), SL_ERROR_FORMAT);
    }
    assert_int_equal(mapping_count(), before);
    free(f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_deterministic),
        cmocka_unit_test(test_mutate_loaded),
        cmocka_unit_test(test_save_over_own_mapping),
        cmocka_unit_test(test_open_dispatch),
        cmocka_unit_test(test_cancel_and_io_errors),
        cmocka_unit_test(test_save_failure_leaves_nothing),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_every_flipped_byte),
        cmocka_unit_test(test_header_lies),
        cmocka_unit_test(test_table_lies),
        cmocka_unit_test(test_newer_minor_version),
        cmocka_unit_test(test_motion_records),
        cmocka_unit_test(test_content_lies),
        cmocka_unit_test(test_metadata_lies),
        cmocka_unit_test(test_hostile_mappings_do_not_leak),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

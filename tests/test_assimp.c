/* Import and export through assimp, and mesh splitting: objects per OBJ group with the Y-up to
 * Z-up rotation, glTF instancing kept as one shared mesh, PLY, --split on a 20k-triangle grid
 * (every triangle kept exactly once, pieces compact), OBJ/GLB/glTF round trips, and bad input
 * (missing, garbage, truncated, NaN) and failing output (no partial files). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "scene/scene_internal.h"
#include "import/split.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "support/counting_alloc.h"

#define DATA SL_SOURCE_DIR "/tests/data/"

/* LeakSanitizer reads this hook at start-up: assimp's own leaks on some bad input (see
 * tests/lsan.supp for the why) are not ours. Our memory is checked by the counting allocator. */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:libassimp.so\n"; }

/* ---- helpers ---- */

static void near_vec(sl_vec3 a, float x, float y, float z, float eps)
{
    if (fabsf(a.x - x) > eps || fabsf(a.y - y) > eps || fabsf(a.z - z) > eps)
        fail_msg("(%g %g %g) != (%g %g %g)", a.x, a.y, a.z, x, y, z);
}

static void near_box(sl_aabb b, float x0, float y0, float z0, float x1, float y1, float z1, float eps)
{
    near_vec(b.min, x0, y0, z0, eps);
    near_vec(b.max, x1, y1, z1, eps);
}

static void same_box(sl_aabb a, sl_aabb b, float eps)
{
    near_box(a, b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z, eps);
}

/* A fresh temporary directory under the build tree. */
static char *make_tmpdir(void)
{
    char *dir = malloc(512);
    assert_non_null(dir);
    snprintf(dir, 512, "%s/test_assimp.XXXXXX", SL_BINARY_DIR);
    assert_non_null(mkdtemp(dir));
    return dir;
}

/* Number of entries in a directory (without . and ..). */
static int dir_entries(const char *dir)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
            n++;
    closedir(d);
    return n;
}

/* Remove a directory and what it holds (one level of subdirectories). */
static void remove_tree(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    char path[1024];
    for (struct dirent *e; (e = readdir(d));) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct stat st;
        if (lstat(path, &st) == 0 && S_ISDIR(st.st_mode))
            remove_tree(path);
        else
            unlink(path);
    }
    closedir(d);
    rmdir(dir);
}

static bool file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static void write_file(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, size, f), size);
    assert_int_equal(fclose(f), 0);
}

static uint64_t instanced_triangles(sl_scene s)
{
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    return st.instanced_triangle_count;
}

/* True when mesh m has a vertex at (x,y,z). */
static bool mesh_has_vertex(sl_scene s, uint32_t m, float x, float y, float z)
{
    sl_mesh_view mv = sl_scene_mesh(s, m);
    for (uint32_t v = 0; v < mv.vertex_count; v++) {
        const float *p = mv.positions + 3 * v;
        if (fabsf(p[0] - x) < 1e-6f && fabsf(p[1] - y) < 1e-6f && fabsf(p[2] - z) < 1e-6f)
            return true;
    }
    return false;
}

/* World-space triangles of a whole scene, 9 floats each, sorted: a multiset fingerprint. */
static int cmp_tri(const void *a, const void *b)
{
    const float *x = a, *y = b;
    for (int i = 0; i < 9; i++)
        if (x[i] != y[i])
            return x[i] < y[i] ? -1 : 1;
    return 0;
}

static float *world_triangles(sl_scene s, size_t *count)
{
    size_t n = (size_t)instanced_triangles(s), k = 0;
    float *t = malloc(n * 9 * sizeof(float) + 1);
    assert_non_null(t);
    for (uint32_t o = 0; o < sl_scene_object_count(s); o++) {
        sl_object_view ov = sl_scene_object(s, o);
        sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
        for (uint32_t i = 0; i < mv.triangle_count; i++, k++)
            for (int c = 0; c < 3; c++) {
                const float *p = mv.positions + 3 * mv.indices[3 * i + c];
                sl_vec3 w = sl_affine_point(&ov.transform, (sl_vec3){p[0], p[1], p[2]});
                t[9 * k + 3 * c] = w.x, t[9 * k + 3 * c + 1] = w.y, t[9 * k + 3 * c + 2] = w.z;
            }
    }
    assert_int_equal(k, n);
    qsort(t, n, 9 * sizeof(float), cmp_tri);
    *count = n;
    return t;
}

/* An n x n grid of unit quads in the plane z = 0 (2 n² triangles). */
static void make_grid(uint32_t n, float **pos, uint32_t *nv, uint32_t **idx, uint32_t *nt)
{
    *nv = (n + 1) * (n + 1);
    *nt = 2 * n * n;
    *pos = malloc(3 * sizeof(float) * *nv);
    *idx = malloc(3 * sizeof(uint32_t) * *nt);
    assert_non_null(*pos);
    assert_non_null(*idx);
    for (uint32_t j = 0; j <= n; j++)
        for (uint32_t i = 0; i <= n; i++) {
            float *p = *pos + 3 * (j * (n + 1) + i);
            p[0] = (float)i, p[1] = (float)j, p[2] = 0;
        }
    uint32_t t = 0;
    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
            uint32_t *q = *idx + 6 * t++;
            q[0] = a, q[1] = b, q[2] = c, q[3] = a, q[4] = c, q[5] = d;
        }
}

/* ---- import ---- */

static void test_obj_groups(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", NULL, &a, &s, &err), SL_OK);
    assert_int_equal(sl_scene_object_count(s), 3);
    assert_int_equal(sl_scene_mesh_count(s), 3);
    /* box (quads), roof (one quad), fan (a pentagon) in file order */
    const uint32_t tris[3] = {12, 2, 3};
    for (uint32_t o = 0; o < 3; o++) {
        sl_object_view ov = sl_scene_object(s, o);
        assert_int_equal(ov.triangle_count, tris[o]);
        assert_int_equal(ov.kind, SL_KIND_IMPORTED);
        assert_true(ov.identity);
    }
    /* Y-up (x,y,z) becomes Z-up (x,-z,y) */
    near_box(sl_scene_object_bounds(s, 0), 0, -3, 0, 1, 0, 2, 0);
    near_box(sl_scene_object_bounds(s, 1), 10, 0, 5, 12, 4, 5, 0);
    near_box(sl_scene_object_bounds(s, 2), -3.5f, 0, 0, -1.5f, 0, 2, 0);
    /* the box corner written as "v 1 2 3" */
    assert_true(mesh_has_vertex(s, sl_scene_object(s, 0).mesh, 1, -3, 2));
    assert_false(mesh_has_vertex(s, sl_scene_object(s, 0).mesh, 1, 2, 3));
    /* colours from groups.mtl: red stays active for the roof, the fan is blue */
    assert_int_equal(sl_scene_object(s, 0).color, 0xff0000ffu);
    assert_int_equal(sl_scene_object(s, 1).color, 0xff0000ffu);
    assert_int_equal(sl_scene_object(s, 2).color, 0x0000ffffu);
    assert_string_equal(sl_scene_meta(s, "source"), "groups.obj");
    assert_int_equal(strlen(sl_scene_meta(s, "source.xxh3")), 16);
    assert_string_equal(sl_scene_meta(s, "importer"), "assimp");
    assert_string_equal(sl_scene_meta(s, "assimp.up_axis"), "y");
    assert_non_null(strstr(sl_scene_meta(s, "assimp.format"), "obj"));
    /* normals come back unit length */
    sl_mesh_view mv = sl_scene_mesh(s, 0);
    for (uint32_t v = 0; v < mv.vertex_count; v++) {
        const float *n = mv.normals + 3 * v;
        assert_true(fabsf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1) < 1e-4f);
    }
    sl_scene_destroy(s);

    /* Z-up file, 2 metres per unit: no rotation, doubled */
    sl_import_options opt;
    memset(&opt, 0, sizeof opt);
    opt.up_axis = SL_UP_Z;
    opt.unit_scale = 2;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", &opt, &a, &s, &err), SL_OK);
    near_box(sl_scene_object_bounds(s, 0), 0, 0, 0, 2, 4, 6, 0);
    assert_true(mesh_has_vertex(s, sl_scene_object(s, 0).mesh, 2, 4, 6));
    assert_string_equal(sl_scene_meta(s, "assimp.unit_scale"), "2");
    sl_scene_destroy(s);
    assert_int_equal(cnt.live, 0);
}

/* instanced.gltf: root translated by (10,0,0); three nodes share the tetrahedron mesh. */
static void test_gltf_instancing(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "instanced.gltf", NULL, &a, &s, &err), SL_OK);
    assert_int_equal(sl_scene_mesh_count(s), 1);
    assert_int_equal(sl_scene_object_count(s), 3);
    assert_int_equal(sl_scene_mesh(s, 0).triangle_count, 4);
    assert_int_equal(instanced_triangles(s), 12);
    for (uint32_t o = 0; o < 3; o++) {
        sl_object_view ov = sl_scene_object(s, o);
        assert_int_equal(ov.mesh, 0);
        assert_int_equal(ov.color, 0xcc3333ffu); /* baseColorFactor 0.8 0.2 0.2 */
        assert_false(ov.identity);
        for (uint32_t q = 0; q < o; q++)
            assert_memory_not_equal(ov.transform.m, sl_scene_object(s, q).transform.m, sizeof ov.transform.m);
    }
    /* inst_a at (10,0,0); inst_b 5 further along x; inst_c scaled 2, turned 90° about Y, at z=-5
     * (file frame), then rotated to Z-up */
    near_box(sl_scene_object_bounds(s, 0), 10, -1, 0, 11, 0, 1, 1e-5f);
    near_box(sl_scene_object_bounds(s, 1), 15, -1, 0, 16, 0, 1, 1e-5f);
    near_box(sl_scene_object_bounds(s, 2), 10, 5, 0, 12, 7, 2, 1e-5f);
    /* the shared mesh is in Z-up: the apex (0,1,0) of the file is at (0,0,1) */
    assert_true(mesh_has_vertex(s, 0, 0, 0, 1));
    sl_scene_destroy(s);
    assert_int_equal(cnt.live, 0);
}

static void test_ply(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "quads.ply", NULL, NULL, &s, &err), SL_OK);
    assert_int_equal(sl_scene_object_count(s), 1);
    assert_int_equal(instanced_triangles(s), 4);
    /* two shared-edge quads: 6 vertices after joining */
    assert_int_equal(sl_scene_mesh(s, 0).vertex_count, 6);
    near_box(sl_scene_bounds(s), 0, 0, 0, 2, 0, 1, 0);
    sl_scene_destroy(s);
}

/* ---- splitting ---- */

static void test_split_grid(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    float *pos;
    uint32_t *idx, nv, nt;
    make_grid(100, &pos, &nv, &idx, &nt);
    assert_int_equal(nt, 20000);
    sl_split_result r, r2;
    sl_error err;
    assert_int_equal(sl_split_mesh(pos, NULL, nv, idx, nt, 1000, &a, &r, &err), SL_OK);
    assert_int_equal(r.piece_count, 20);
    assert_int_equal(r.triangle_count, nt);
    assert_null(r.normals);
    /* every input triangle exactly once, with its own corners */
    uint8_t *seen = calloc(nt, 1);
    assert_non_null(seen);
    uint32_t total = 0;
    for (uint32_t p = 0; p < r.piece_count; p++) {
        const sl_split_piece *pc = &r.pieces[p];
        assert_true(pc->triangle_count <= 1000 && pc->triangle_count >= 999);
        assert_int_equal(pc->first_triangle, total);
        total += pc->triangle_count;
        /* compact: a twentieth of a 100 x 100 grid is far below a quarter of it */
        float w = pc->bounds.max.x - pc->bounds.min.x, h = pc->bounds.max.y - pc->bounds.min.y;
        assert_true(w * h <= 100 * 100 / 8.0f);
        assert_true(w <= 51 && h <= 51);
        for (uint32_t i = pc->first_triangle; i < pc->first_triangle + pc->triangle_count; i++) {
            uint32_t src = r.source_triangle[i];
            assert_true(src < nt);
            assert_int_equal(seen[src], 0);
            seen[src] = 1;
            if (i > pc->first_triangle)
                assert_true(src > r.source_triangle[i - 1]); /* input order within a piece */
            for (int c = 0; c < 3; c++) {
                uint32_t li = r.indices[3 * i + c];
                assert_true(li < pc->vertex_count);
                const float *got = r.positions + 3 * (pc->first_vertex + li), *want = pos + 3 * idx[3 * src + c];
                assert_memory_equal(got, want, 3 * sizeof(float));
            }
        }
    }
    assert_int_equal(total, nt);
    free(seen);
    /* deterministic */
    assert_int_equal(sl_split_mesh(pos, NULL, nv, idx, nt, 1000, &a, &r2, &err), SL_OK);
    assert_int_equal(r2.vertex_count, r.vertex_count);
    assert_memory_equal(r2.indices, r.indices, 3 * sizeof(uint32_t) * nt);
    assert_memory_equal(r2.positions, r.positions, 3 * sizeof(float) * r.vertex_count);
    sl_split_free(&a, &r2);
    sl_split_free(&a, &r);

    /* small enough: one compacted piece; empty: no pieces; bad index: an error */
    assert_int_equal(sl_split_mesh(pos, NULL, nv, idx, 6, 1000, &a, &r, &err), SL_OK);
    assert_int_equal(r.piece_count, 1);
    assert_int_equal(r.vertex_count, 8); /* the first 3 quads of a row: 2 x 4 grid vertices */
    sl_split_free(&a, &r);
    assert_int_equal(sl_split_mesh(pos, NULL, nv, idx, 0, 10, &a, &r, &err), SL_OK);
    assert_int_equal(r.piece_count, 0);
    idx[7] = nv;
    assert_int_equal(sl_split_mesh(pos, NULL, nv, idx, nt, 10, &a, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "out of range"));
    assert_int_equal(sl_split_mesh(pos, NULL, nv, idx, nt, 0, &a, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    free(pos);
    free(idx);
    assert_int_equal(cnt.live, 0);
}

/* The same grid written as an OBJ file, imported with --split 1000. */
static void test_split_import(void **state)
{
    (void)state;
    float *pos;
    uint32_t *idx, nv, nt;
    make_grid(100, &pos, &nv, &idx, &nt);
    char *dir = make_tmpdir(), path[600];
    snprintf(path, sizeof path, "%s/grid.obj", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "o grid\n");
    for (uint32_t v = 0; v < nv; v++) /* Z-up grid written Y-up: (x, z, -y) */
        fprintf(f, "v %g %g %g\n", pos[3 * v], pos[3 * v + 2], -pos[3 * v + 1]);
    for (uint32_t t = 0; t < nt; t++)
        fprintf(f, "f %u %u %u\n", idx[3 * t] + 1, idx[3 * t + 1] + 1, idx[3 * t + 2] + 1);
    assert_int_equal(fclose(f), 0);

    sl_scene whole, split;
    sl_error err;
    assert_int_equal(sl_import_assimp(path, NULL, NULL, &whole, &err), SL_OK);
    assert_int_equal(sl_scene_object_count(whole), 1);
    near_box(sl_scene_bounds(whole), 0, 0, 0, 100, 100, 0, 1e-5f);
    sl_import_options opt;
    memset(&opt, 0, sizeof opt);
    opt.split_triangles = 1000;
    assert_int_equal(sl_import_assimp(path, &opt, NULL, &split, &err), SL_OK);
    uint32_t n = sl_scene_object_count(split);
    assert_true(n >= 18 && n <= 22);
    assert_int_equal(sl_scene_mesh_count(split), n);
    assert_int_equal(instanced_triangles(split), 20000);
    assert_string_equal(sl_scene_meta(split, "assimp.split_triangles"), "1000");
    for (uint32_t o = 0; o < n; o++) {
        sl_aabb b = sl_scene_object_bounds(split, o);
        assert_true(sl_scene_object(split, o).triangle_count <= 1000);
        assert_true((b.max.x - b.min.x) * (b.max.y - b.min.y) <= 100 * 100 / 8.0f);
    }
    /* the multiset of world triangles is unchanged */
    size_t na, nb;
    float *ta = world_triangles(whole, &na), *tb = world_triangles(split, &nb);
    assert_int_equal(na, nb);
    assert_memory_equal(ta, tb, na * 9 * sizeof(float));
    free(ta);
    free(tb);
    sl_scene_destroy(whole);
    sl_scene_destroy(split);
    remove_tree(dir);
    free(dir);
    free(pos);
    free(idx);
}

/* ---- export ---- */

/* Export s to dir/name with up axis `up`, re-import it reading `read_up`, compare counts and
 * bounds. */
static sl_scene round_trip(sl_scene s, const char *dir, const char *name, const char *format, sl_up_axis up,
                           sl_up_axis read_up)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    sl_error err;
    if (sl_export_assimp(s, path, format, up, &err) != SL_OK)
        fail_msg("export %s: %s", name, err.message);
    sl_import_options opt;
    memset(&opt, 0, sizeof opt);
    opt.up_axis = read_up;
    sl_scene back;
    if (sl_import_assimp(path, &opt, NULL, &back, &err) != SL_OK)
        fail_msg("re-import %s: %s", name, err.message);
    assert_int_equal(instanced_triangles(back), instanced_triangles(s));
    same_box(sl_scene_bounds(back), sl_scene_bounds(s), 1e-4f);
    return back;
}

/* A hand-built Z-up scene: a shared box under three rotations, and a coloured ramp. */
static sl_scene build_scene(const sl_allocator *a)
{
    static const float box[] = {0, 0, 0, 2, 0, 0, 2, 1, 0, 0, 1, 0, 0, 0, 3, 2, 0, 3, 2, 1, 3, 0, 1, 3};
    static const uint32_t box_idx[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                       1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    static const float ramp[] = {0, 0, 0, 4, 0, 0, 4, 2, 1, 0, 2, 1};
    static const uint32_t ramp_idx[] = {0, 1, 2, 0, 2, 3};
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(a, &s, &err), SL_OK);
    uint32_t mb, mr;
    sl_mesh_desc d = {box, NULL, 8, box_idx, 12, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &d, &mb, &err), SL_OK);
    sl_mesh_desc d2 = {ramp, NULL, 4, ramp_idx, 2, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &d2, &mr, &err), SL_OK);
    const float c30 = 0.8660254f, s30 = 0.5f;
    sl_affine t[3] = {{{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}},
                      {{c30, -s30, 0, 10, s30, c30, 0, -4, 0, 0, 1, 0.5f}},          /* 30° about z */
                      {{1, 0, 0, -6, 0, c30, -s30, 3, 0, s30, c30, 1}}};              /* 30° about x */
    for (int i = 0; i < 3; i++) {
        sl_object_desc o = {mb, &t[i], 0x336699ffu, SL_KIND_BUILDING, 0, 0};
        assert_int_equal(sl_scene_add_object(s, &o, NULL, &err), SL_OK);
    }
    sl_object_desc o = {mr, NULL, 0xff8000ffu, SL_KIND_GROUND, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &o, NULL, &err), SL_OK);
    return s;
}

static void test_export_round_trip(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    char *dir = make_tmpdir();
    sl_scene s = build_scene(&a);

    /* GLB keeps nodes, instancing, transforms and colours */
    sl_scene back = round_trip(s, dir, "scene.glb", NULL, SL_UP_Y, SL_UP_Y);
    assert_int_equal(sl_scene_object_count(back), 4);
    assert_int_equal(sl_scene_mesh_count(back), 2);
    for (uint32_t o = 0; o < 4; o++) {
        same_box(sl_scene_object_bounds(back, o), sl_scene_object_bounds(s, o), 1e-4f);
        assert_int_equal(sl_scene_object(back, o).color, sl_scene_object(s, o).color);
    }
    sl_scene_destroy(back);
    assert_int_equal(dir_entries(dir), 1);

    /* OBJ (with its .mtl) expands instances into world-space groups */
    back = round_trip(s, dir, "scene.obj", NULL, SL_UP_Y, SL_UP_Y);
    assert_int_equal(sl_scene_object_count(back), 4);
    for (uint32_t o = 0; o < 4; o++) {
        same_box(sl_scene_object_bounds(back, o), sl_scene_object_bounds(s, o), 1e-4f);
        assert_int_equal(sl_scene_object(back, o).color, sl_scene_object(s, o).color);
    }
    sl_scene_destroy(back);
    assert_int_equal(dir_entries(dir), 3); /* + scene.obj, scene.mtl */

    /* Z-up OBJ read back as Z-up */
    back = round_trip(s, dir, "zup.obj", "obj", SL_UP_Z, SL_UP_Z);
    sl_scene_destroy(back);

    /* glTF text: the .bin side file is named after the output and found again */
    back = round_trip(s, dir, "scene.gltf", NULL, SL_UP_Z /* ignored: glTF is Y-up */, SL_UP_Y);
    sl_scene_destroy(back);
    char path[700];
    snprintf(path, sizeof path, "%s/scene.bin", dir);
    assert_true(file_exists(path));
    assert_int_equal(dir_entries(dir), 7); /* glb, obj, mtl, zup.obj, zup.mtl, gltf, bin: no temporaries */

    /* an imported scene (shared mesh, node hierarchy) survives GLB */
    sl_scene g;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "instanced.gltf", NULL, &a, &g, &err), SL_OK);
    back = round_trip(g, dir, "inst.glb", NULL, SL_UP_Y, SL_UP_Y);
    assert_int_equal(sl_scene_mesh_count(back), 1);
    assert_int_equal(sl_scene_object_count(back), 3);
    for (uint32_t o = 0; o < 3; o++)
        same_box(sl_scene_object_bounds(back, o), sl_scene_object_bounds(g, o), 1e-4f);
    sl_scene_destroy(back);
    sl_scene_destroy(g);

    sl_scene_destroy(s);
    remove_tree(dir);
    free(dir);
    assert_int_equal(cnt.live, 0);
}

/* ---- bad input and failing output ---- */

static void expect_import_error(const char *path, sl_status want, const char *needle)
{
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s = (sl_scene)(uintptr_t)1;
    sl_error err = {0};
    sl_status st = sl_import_assimp(path, NULL, &a, &s, &err);
    if (st == SL_OK)
        fail_msg("%s: import should have failed", path);
    if (want != SL_OK)
        assert_int_equal(st, want);
    assert_int_equal(err.status, st);
    assert_null(s);
    if (!strstr(err.message, path) || (needle && !strstr(err.message, needle)))
        fail_msg("%s: unexpected message '%s'", path, err.message);
    assert_int_equal(cnt.live, 0);
}

static void test_bad_input(void **state)
{
    (void)state;
    char *dir = make_tmpdir(), path[700];
    expect_import_error(DATA "does-not-exist.obj", SL_ERROR_NOT_FOUND, "No such file");
    expect_import_error(dir, SL_ERROR_IO, "not a regular file");

    static const unsigned char garbage[] = {0x7f, 'E', 'L', 'F', 0, 0xff, 0xfe, 0x13, 0x37, 0, 0, 1, 0x80, 0x81};
    snprintf(path, sizeof path, "%s/garbage.gltf", dir);
    write_file(path, garbage, sizeof garbage);
    expect_import_error(path, SL_ERROR_FORMAT, NULL);
    snprintf(path, sizeof path, "%s/garbage.glb", dir);
    write_file(path, garbage, sizeof garbage);
    expect_import_error(path, SL_ERROR_FORMAT, NULL);
    snprintf(path, sizeof path, "%s/empty.obj", dir);
    write_file(path, "", 0);
    expect_import_error(path, SL_ERROR_FORMAT, NULL);
    /* an OBJ with only lines and points has nothing to see */
    snprintf(path, sizeof path, "%s/lines.obj", dir);
    static const char lines[] = "v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2\nl 2 3\np 1\n";
    write_file(path, lines, sizeof lines - 1);
    expect_import_error(path, SL_ERROR_FORMAT, NULL);

    /* a face pointing past the vertices, in the second object (assimp leaks the first one's mesh
     * here: tests/lsan.supp) */
    snprintf(path, sizeof path, "%s/range.obj", dir);
    static const char range[] = "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nf 1 2 9\n";
    write_file(path, range, sizeof range - 1);
    expect_import_error(path, SL_ERROR_FORMAT, "out of range");

    /* truncated glTF: every prefix of the file fails cleanly */
    FILE *f = fopen(DATA "instanced.gltf", "rb");
    assert_non_null(f);
    char buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_true(n > 200 && n < sizeof buf);
    snprintf(path, sizeof path, "%s/truncated.gltf", dir);
    for (size_t cut = 1; cut < n - 8; cut += n / 13) {
        write_file(path, buf, cut);
        expect_import_error(path, SL_ERROR_FORMAT, NULL);
    }

    /* NaN vertex: the node and the mesh are named */
    expect_import_error(DATA "nan.obj", SL_ERROR_FORMAT, "node 'broken'");
    expect_import_error(DATA "nan.obj", SL_ERROR_FORMAT, "vertex 2: position.x is NaN");
    snprintf(path, sizeof path, "%s/inf.obj", dir);
    static const char inf[] = "o tower\nv 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n";
    write_file(path, inf, sizeof inf - 1);
    expect_import_error(path, SL_ERROR_FORMAT, "vertex 2: position.y is +inf");

    /* bad options */
    sl_import_options opt;
    memset(&opt, 0, sizeof opt);
    opt.unit_scale = -1;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", &opt, NULL, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    opt.unit_scale = NAN;
    assert_int_equal(sl_import_assimp(DATA "groups.obj", &opt, NULL, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    remove_tree(dir);
    free(dir);
}

static void test_export_failures(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    char *dir = make_tmpdir(), path[700];
    sl_scene s = build_scene(&a);
    sl_error err;

    /* a directory that does not exist */
    snprintf(path, sizeof path, "%s/missing/out.obj", dir);
    assert_int_equal(sl_export_assimp(s, path, NULL, SL_UP_Y, &err), SL_ERROR_IO);
    assert_non_null(strstr(err.message, "out.obj"));
    assert_int_equal(dir_entries(dir), 0);

    /* a directory we may not write (root may write anywhere: then this case is skipped) */
    if (geteuid() != 0) {
        char ro[600];
        snprintf(ro, sizeof ro, "%s/ro", dir);
        assert_int_equal(mkdir(ro, 0555), 0);
        snprintf(path, sizeof path, "%s/out.glb", ro);
        assert_int_equal(sl_export_assimp(s, path, NULL, SL_UP_Y, &err), SL_ERROR_IO);
        assert_int_equal(dir_entries(ro), 0);
        chmod(ro, 0755);
        rmdir(ro);
    }

    /* the main file cannot be renamed into place (a directory is in the way): the .mtl that was
     * already moved is taken back and no temporary is left */
    snprintf(path, sizeof path, "%s/blocked.obj", dir);
    assert_int_equal(mkdir(path, 0755), 0);
    assert_int_not_equal(sl_export_assimp(s, path, NULL, SL_UP_Y, &err), SL_OK);
    assert_int_equal(dir_entries(dir), 1);
    rmdir(path);

    /* formats */
    snprintf(path, sizeof path, "%s/out.xyz", dir);
    assert_int_equal(sl_export_assimp(s, path, NULL, SL_UP_Y, &err), SL_ERROR_UNSUPPORTED);
    assert_int_equal(sl_export_assimp(s, path, "no-such-format", SL_UP_Y, &err), SL_ERROR_NOT_FOUND);
    snprintf(path, sizeof path, "%s/out", dir);
    assert_int_equal(sl_export_assimp(s, path, NULL, SL_UP_Y, &err), SL_ERROR_INVALID_ARGUMENT);
    snprintf(path, sizeof path, "%s/out.3mf", dir);
    assert_int_equal(sl_export_assimp(s, path, NULL, SL_UP_Y, &err), SL_ERROR_UNSUPPORTED);
    assert_int_equal(sl_export_assimp(s, path, NULL, (sl_up_axis)7, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(dir_entries(dir), 0);

    /* an explicit format id beats the extension */
    snprintf(path, sizeof path, "%s/binary.stl", dir);
    assert_int_equal(sl_export_assimp(s, path, "stlb", SL_UP_Y, &err), SL_OK);
    assert_int_equal(dir_entries(dir), 1);

    /* nothing to export */
    sl_scene empty;
    assert_int_equal(sl_scene_create(&a, &empty, &err), SL_OK);
    snprintf(path, sizeof path, "%s/empty.obj", dir);
    assert_int_equal(sl_export_assimp(empty, path, NULL, SL_UP_Y, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_false(file_exists(path));
    sl_scene_destroy(empty);

    sl_scene_destroy(s);
    remove_tree(dir);
    free(dir);
    assert_int_equal(cnt.live, 0);
}

/* ---- issue 12: same bytes for the same scene, messages that keep the reason ---- */

static uint8_t *read_whole(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("%s: %s", path, strerror(errno));
    assert_int_equal(fseek(f, 0, SEEK_END), 0);
    long n = ftell(f);
    assert_true(n > 0);
    rewind(f);
    uint8_t *p = malloc((size_t)n);
    assert_non_null(p);
    assert_int_equal(fread(p, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *size = (size_t)n;
    return p;
}

/* COLLADA and FBX exports a second apart are byte-identical (assimp writes the time of writing
 * into both) and still import back (binary FBX excepted: assimp 5.2 cannot read the binary FBX
 * its own exporter writes, "block offset is out of range", with or without this). */
static void test_export_deterministic(void **state)
{
    (void)state;
    char *dir = make_tmpdir(), a[700], b[700];
    sl_scene s = build_scene(NULL);
    sl_error err;
    static const struct { const char *name, *format; bool reads_back; } cases[] = {
        {"x.dae", NULL, true}, {"x.fbx", NULL, false}, {"ascii.fbx", "fbxa", true}};
    for (int pass = 0; pass < 2; pass++) {
        if (pass)
            usleep(1100 * 1000); /* the clock assimp reads has a one-second resolution */
        for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
            snprintf(a, sizeof a, "%s/%d-%s", dir, pass, cases[i].name);
            if (sl_export_assimp(s, a, cases[i].format, SL_UP_Y, &err) != SL_OK)
                fail_msg("export %s: %s", a, err.message);
        }
    }
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(a, sizeof a, "%s/0-%s", dir, cases[i].name);
        snprintf(b, sizeof b, "%s/1-%s", dir, cases[i].name);
        size_t na, nb;
        uint8_t *pa = read_whole(a, &na), *pb = read_whole(b, &nb);
        if (na != nb || memcmp(pa, pb, na) != 0)
            fail_msg("%s and %s differ (%zu and %zu bytes)", a, b, na, nb);
        free(pa);
        free(pb);
        if (cases[i].reads_back) {
            sl_scene back;
            if (sl_import_assimp(a, NULL, NULL, &back, &err) != SL_OK)
                fail_msg("re-import %s: %s", a, err.message);
            assert_int_equal(instanced_triangles(back), instanced_triangles(s));
            sl_scene_destroy(back);
        }
    }
    /* the one-triangle scene that assimp 5.2 refused to write as STL and OBJ (a scene flagged
     * as sharing vertices that shares none) */
    static const float tri[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const uint32_t tri_idx[] = {0, 1, 2};
    sl_scene one;
    assert_int_equal(sl_scene_create(NULL, &one, &err), SL_OK);
    uint32_t m;
    sl_mesh_desc d = {tri, NULL, 3, tri_idx, 1, NULL};
    assert_int_equal(sl_scene_add_mesh(one, &d, &m, &err), SL_OK);
    sl_object_desc o = {m, NULL, 0xff0000ffu, SL_KIND_IMPORTED, 0, 0};
    assert_int_equal(sl_scene_add_object(one, &o, NULL, &err), SL_OK);
    static const char *one_names[] = {"one.stl", "one.obj", "one.ply"};
    for (size_t i = 0; i < 3; i++) {
        sl_scene back = round_trip(one, dir, one_names[i], NULL, SL_UP_Y, SL_UP_Y);
        sl_scene_destroy(back);
    }
    sl_scene_destroy(one);
    sl_scene_destroy(s);
    remove_tree(dir);
    free(dir);
}

/* A write that fails names the file and the reason (here: the file size limit, EFBIG). */
static void test_export_write_error(void **state)
{
    (void)state;
    char *dir = make_tmpdir(), path[700];
    sl_scene s = build_scene(NULL);
    sl_error err;
    struct rlimit old, small = {2000, 2000};
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
    small.rlim_max = old.rlim_max;
    void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
    static const char *names[] = {"big.obj", "big.dae", "big.ply"};
    sl_status st[3];
    sl_error errs[3];
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &small), 0);
    for (int i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        st[i] = sl_export_assimp(s, path, NULL, SL_UP_Y, &errs[i]);
    }
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &old), 0);
    signal(SIGXFSZ, prev);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(st[i], SL_ERROR_IO);
        if (!strstr(errs[i].message, names[i]) || !strstr(errs[i].message, strerror(EFBIG)))
            fail_msg("%s: the message lacks the file or the reason: '%s'", names[i], errs[i].message);
    }
    assert_int_equal(dir_entries(dir), 0);
    (void)err;
    sl_scene_destroy(s);
    remove_tree(dir);
    free(dir);
}

/* PLY element counts beyond what the file can hold fail before assimp allocates for them. */
static void test_ply_counts(void **state)
{
    (void)state;
    char *dir = make_tmpdir(), path[700];
    static const char ascii[] = "ply\nformat ascii 1.0\nelement vertex 2147483648\nproperty float x\nproperty float y\n"
                                "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    snprintf(path, sizeof path, "%s/huge.ply", dir);
    write_file(path, ascii, sizeof ascii - 1);
    expect_import_error(path, SL_ERROR_FORMAT, "element vertex: 2147483648 declared, the file can hold at most 4 ");
    /* binary: 12 bytes a vertex; 40 bytes after the header hold 3 vertices and 4 bytes */
    char bin[512];
    int hl = snprintf(bin, sizeof bin,
                      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
                      "property float y\nproperty float z\nend_header\n");
    memset(bin + hl, 0, 40);
    snprintf(path, sizeof path, "%s/huge_bin.ply", dir);
    write_file(path, bin, (size_t)hl + 40);
    expect_import_error(path, SL_ERROR_FORMAT, "element vertex: 4000000000 declared, the file can hold at most 3 ");
    /* faces after the vertices: what is left after 3 vertices of 12 bytes */
    hl = snprintf(bin, sizeof bin,
                  "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 99999999\nproperty list uchar int vertex_indices\nend_header\n");
    memset(bin + hl, 0, 36 + 13);
    snprintf(path, sizeof path, "%s/faces.ply", dir);
    write_file(path, bin, (size_t)hl + 36 + 13);
    expect_import_error(path, SL_ERROR_FORMAT, "element face: 99999999 declared, the file can hold at most 13 ");
    /* more vertices than a mesh holds at all */
    static const char many[] = "ply\nformat ascii 1.0\nelement vertex 99999999999\nproperty float x\nend_header\n";
    snprintf(path, sizeof path, "%s/many.ply", dir);
    write_file(path, many, sizeof many - 1);
    expect_import_error(path, SL_ERROR_LIMIT, "element vertex: 99999999999 declared");
    /* a malformed header that made assimp 5.2 read out of bounds (SIGSEGV; fuzz/fuzz_assimp.c) */
    expect_import_error(DATA "ply_bad_header.ply", SL_ERROR_FORMAT, "PLY header line 4: property before any element");
    /* a header line of free text (Blender 2.47's "Created by ...") is skipped, as assimp does */
    snprintf(path, sizeof path, "%s/freetext.ply", dir);
    {
        static const char text[] = "ply\nformat ascii 1.0\nCreated by Blender3D 247 - www.blender.org, source file: ''\n"
                                   "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                   "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        write_file(path, text, sizeof text - 1);
        sl_scene fs;
        sl_error ferr;
        if (sl_import_assimp(path, NULL, NULL, &fs, &ferr) != SL_OK)
            fail_msg("free-text PLY header line refused: %s", ferr.message);
        sl_scene_destroy(fs);
    }
    static const char early[] = "ply\nformat ascii 1.0\nproperty float x\nelement vertex 1\nend_header\n0\n";
    snprintf(path, sizeof path, "%s/early.ply", dir);
    write_file(path, early, sizeof early - 1);
    expect_import_error(path, SL_ERROR_FORMAT, "PLY header line 3: property before any element");
    /* a face without indices: assimp 5.2's post-processing freed the scene twice (SIGSEGV) */
    expect_import_error(DATA "ply_empty_face.ply", SL_ERROR_FORMAT, "face 0 has no vertex indices");
    /* no end_header: assimp 5.2 never returned */
    expect_import_error(DATA "ply_no_end_header.ply", SL_ERROR_FORMAT, "no end_header before the end of the file");
    /* "Ply": assimp takes the magic in any case, and 5.2 looped for ever on this fuzzed header */
    expect_import_error(DATA "ply_mixed_case_hang.ply", SL_ERROR_FORMAT, "PLY header line 3");
    {
        static const char mixed[] = "pLy\nformat ascii 1.0\ncomment no end\nelement vertex 1\n";
        snprintf(path, sizeof path, "%s/mixed.ply", dir);
        write_file(path, mixed, sizeof mixed - 1);
        expect_import_error(path, SL_ERROR_FORMAT, "no end_header before the end of the file");
    }
    /* a valid file is untouched by the check */
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_import_assimp(DATA "quads.ply", NULL, NULL, &s, &err), SL_OK);
    sl_scene_destroy(s);
    remove_tree(dir);
    free(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_obj_groups),       cmocka_unit_test(test_gltf_instancing),
        cmocka_unit_test(test_ply),              cmocka_unit_test(test_split_grid),
        cmocka_unit_test(test_split_import),     cmocka_unit_test(test_export_round_trip),
        cmocka_unit_test(test_bad_input),        cmocka_unit_test(test_export_failures),
        cmocka_unit_test(test_export_deterministic), cmocka_unit_test(test_export_write_error),
        cmocka_unit_test(test_ply_counts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

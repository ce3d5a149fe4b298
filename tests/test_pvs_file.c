/* The .slpvs file: sets written and read back exactly (empty sets, full sets, a partial last
 * block), deterministic bytes, figures and metadata; every single-byte corruption and every
 * truncation is refused (at load or by verify) without a crash or a leak; a newer major version is
 * refused as unsupported; bad writer input leaves no file. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/pvs.h"
#include "support/counting_alloc.h"
#include "support/city_views.h"

#define NCELL 70  /* three blocks of 32, the last partial */
#define NOBJ 1000

static char g_dir[256];

static void path_of(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

/* NCELL unit cells in a row (tests/support/city_views.h) */
static sl_viewcells make_cells(const sl_allocator *a)
{
    sl_viewcells vc = sl_test_row_cells(NCELL, a);
    assert_non_null(vc);
    return vc;
}

/* Cell i sees a pseudo-random ascending set: cell 0 nothing, cell 1 everything. */
static void make_sets(uint64_t *off, uint32_t **ids_out)
{
    uint32_t *ids = malloc((size_t)NCELL * NOBJ * sizeof *ids);
    sl_rng r;
    sl_rng_seed(&r, 11, 0);
    uint64_t at = 0;
    for (int c = 0; c < NCELL; c++) {
        off[c] = at;
        for (uint32_t o = 0; o < NOBJ; o++) {
            bool in = c == 0 ? false : c == 1 ? true : sl_rng_below(&r, 100) < (uint32_t)(c % 20);
            if (in)
                ids[at++] = o;
        }
    }
    off[NCELL] = at;
    *ids_out = ids;
}

static uint8_t *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc((size_t)n);
    assert_int_equal(fread(b, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *size = (size_t)n;
    return b;
}

static void test_roundtrip(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    sl_viewcells vc = make_cells(&a);
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    make_sets(off, &ids);
    char p1[300], p2[300];
    path_of(p1, sizeof p1, "a.slpvs");
    path_of(p2, sizeof p2, "b.slpvs");
    const char *meta = "method=test\noptions=x=1\nguarantee=conservative\n";
    assert_int_equal(sl_pvs_write(p1, vc, NOBJ, 0x1234, off, ids, meta, &err), SL_OK);
    assert_int_equal(sl_pvs_write(p2, vc, NOBJ, 0x1234, off, ids, meta, &err), SL_OK);
    size_t n1, n2;
    uint8_t *b1 = read_file(p1, &n1), *b2 = read_file(p2, &n2);
    assert_int_equal(n1, n2);
    assert_memory_equal(b1, b2, n1);
    assert_int_equal(n1 % 64, 0);
    free(b2);

    sl_pvs p;
    assert_int_equal(sl_pvs_load(p1, &a, &p, &err), SL_OK);
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    assert_int_equal(in.version_major, 1);
    assert_int_equal(in.cell_count, NCELL);
    assert_int_equal(in.object_count, NOBJ);
    assert_int_equal(in.block_count, 3);
    assert_true(in.scene_key == 0x1234);
    assert_true(in.cells_key == sl_viewcells_key(vc));
    assert_int_equal(in.visible_total, off[NCELL]);
    assert_int_equal(in.min_visible, 0);
    assert_int_equal(in.max_visible, NOBJ);
    assert_int_equal(in.file_size, n1);
    assert_true(in.data_bytes < in.raw_bytes);
    assert_string_equal(sl_pvs_meta(p, "method"), "test");
    assert_string_equal(sl_pvs_meta(p, "options"), "x=1");
    assert_null(sl_pvs_meta(p, "absent"));
    assert_null(sl_pvs_meta(p, "metho"));
    assert_string_equal(sl_pvs_meta_text(p), meta);
    assert_int_equal(sl_viewcells_count(sl_pvs_cells(p)), NCELL);
    uint32_t *got = malloc(NOBJ * sizeof *got), n;
    /* out of order on purpose: the block cache must follow */
    for (int k = 0; k < NCELL; k++) {
        int c = (k * 37) % NCELL;
        assert_int_equal(sl_pvs_cell_count(p, (uint32_t)c), off[c + 1] - off[c]);
        assert_int_equal(sl_pvs_cell_set(p, (uint32_t)c, got, NOBJ, &n, &err), SL_OK);
        assert_int_equal(n, off[c + 1] - off[c]);
        if (n)
            assert_memory_equal(got, ids + off[c], n * sizeof *got);
    }
    assert_int_equal(sl_pvs_cell_set(p, 1, got, 10, &n, &err), SL_ERROR_INVALID_ARGUMENT); /* capacity */
    assert_int_equal(sl_pvs_cell_set(p, NCELL, got, NOBJ, &n, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_pvs_verify(p, &err), SL_OK);
    sl_pvs_destroy(p);

    /* from memory too */
    assert_int_equal(sl_pvs_load_memory(b1, n1, "mem", &a, &p, &err), SL_OK);
    assert_int_equal(sl_pvs_verify(p, &err), SL_OK);
    sl_pvs_destroy(p);
    free(b1);
    free(got);
    free(ids);
    sl_viewcells_destroy(vc);
    assert_int_equal(cnt.live, 0);
}

/* Every single-byte change is caught at load or by verify; every truncation at load. */
static void test_corruption(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    sl_viewcells vc = make_cells(NULL);
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    make_sets(off, &ids);
    char p1[300];
    path_of(p1, sizeof p1, "c.slpvs");
    assert_int_equal(sl_pvs_write(p1, vc, NOBJ, 7, off, ids, "k=v\n", &err), SL_OK);
    size_t n;
    uint8_t *b = read_file(p1, &n);
    uint8_t *m = malloc(n);
    size_t step = getenv("SL_SANITIZED") ? 7 : 1;
    for (size_t i = 0; i < n; i += step) {
        memcpy(m, b, n);
        m[i] ^= 0x5a;
        sl_pvs p;
        sl_status st = sl_pvs_load_memory(m, n, "corrupt", &a, &p, &err);
        if (st == SL_OK) {
            st = sl_pvs_verify(p, &err);
            sl_pvs_destroy(p);
        }
        if (st == SL_OK)
            fail_msg("a change of byte %zu went unnoticed", i);
        assert_non_null(strstr(err.message, "corrupt"));
    }
    for (size_t len = 0; len < n; len += step * 5) {
        sl_pvs p;
        assert_int_not_equal(sl_pvs_load_memory(b, len, "short", &a, &p, &err), SL_OK);
    }
    assert_int_equal(cnt.live, 0);

    /* a newer major version is unsupported, not malformed */
    memcpy(m, b, n);
    m[8] = 2;
    uint64_t h = sl_hash64(m, 56, 0);
    memcpy(m + 56, &h, 8);
    sl_pvs p;
    assert_int_equal(sl_pvs_load_memory(m, n, "new", NULL, &p, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "newer"));
    free(m);
    free(b);
    free(ids);
    sl_viewcells_destroy(vc);
}

/* Bad input to the writer: refused, and no file is left behind. */
static void test_writer_input(void **state)
{
    (void)state;
    sl_error err;
    sl_viewcells vc = make_cells(NULL);
    uint64_t off[NCELL + 1];
    uint32_t *ids;
    make_sets(off, &ids);
    char p1[300];
    path_of(p1, sizeof p1, "bad.slpvs");
    unlink(p1);
    uint32_t save = ids[off[5] + 1];
    ids[off[5] + 1] = ids[off[5]]; /* not strictly ascending */
    assert_int_equal(sl_pvs_write(p1, vc, NOBJ, 7, off, ids, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "cell 5"));
    ids[off[5] + 1] = save;
    assert_int_equal(sl_pvs_write(p1, vc, 10, 7, off, ids, NULL, &err), SL_ERROR_INVALID_ARGUMENT); /* ids >= 10 */
    assert_int_equal(access(p1, F_OK), -1);
    char nodir[300];
    path_of(nodir, sizeof nodir, "no/such/dir/x.slpvs");
    assert_int_equal(sl_pvs_write(nodir, vc, NOBJ, 7, off, ids, NULL, &err), SL_ERROR_IO);
    sl_pvs p;
    assert_int_equal(sl_pvs_load(p1, NULL, &p, &err), SL_ERROR_NOT_FOUND);
    free(ids);
    sl_viewcells_destroy(vc);
}

/* The scene key follows what the sets depend on, and ignores moving objects. */
static void test_scene_key(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t idx[3] = {0, 1, 2}, mesh, car;
    sl_mesh_desc md = {pos, NULL, 3, idx, 1, NULL};
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0, SL_KIND_CAR, SL_OBJECT_DYNAMIC, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &car, &err), SL_OK);
    uint64_t k0 = sl_pvs_scene_key(s);
    sl_affine t = sl_affine_identity();
    t.m[3] = 5;
    assert_int_equal(sl_scene_set_object_transform(s, car, &t, &err), SL_OK);
    assert_true(sl_pvs_scene_key(s) == k0);
    float xy[8] = {0, 0, 1, 0, 1, 1, 0, 1};
    sl_footprint_desc fd = {xy, 4, 0, 10, SL_NONE};
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    assert_true(sl_pvs_scene_key(s) != k0);
    sl_scene_destroy(s);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "%s/test_pvs_file.XXXXXX", SL_BINARY_DIR);
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_corruption),
        cmocka_unit_test(test_writer_input),
        cmocka_unit_test(test_scene_key),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

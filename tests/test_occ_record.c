/* The occlusion recording (record=FILE, `sightline occlusion replay`) carries a checksum: a file
 * damaged anywhere is refused with the file, the offset and the reason, instead of replaying as
 * "ok" (issue 12: version 1 had none, and most single-byte corruptions replayed cleanly). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "cull/occlusion_debug.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "support/city_views.h"

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(p, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* Record frame 1 of a short street walk through the tiny city with `method`. */
static void record(const char *method, const char *rec)
{
    sl_scene s;
    sl_error err;
    sl_path p;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, 3, 8, 320, 240, &s, &p, &err), SL_OK);
    char opts[400];
    snprintf(opts, sizeof opts, "record=%s,debug_frame=1", rec);
    sl_culler c;
    assert_int_equal(sl_culler_create(method, s, opts, NULL, &c, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), k, *out = malloc(n * sizeof *out);
    assert_non_null(out);
    for (uint32_t f = 0; f < 2; f++) {
        sl_camera cam = sl_path_camera(p, f);
        if (sl_culler_cull(c, &cam, out, n, &k, &err) != SL_OK)
            fail_msg("%s", err.message);
    }
    sl_culler_destroy(c);
    sl_path_destroy(p);
    sl_scene_destroy(s);
    free(out);
}

static void test_flipped_bytes_refused(void **state)
{
    (void)state;
    char dir[] = "/tmp/sl_occrec_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char rec[300], bad[300];
    snprintf(rec, sizeof rec, "%s/f.rec", dir);
    snprintf(bad, sizeof bad, "%s/bad.rec", dir);
    record("hzb", rec);
    sl_error err;
    uint8_t *bytes;
    size_t size;
    assert_int_equal(sl_file_read_all(sl_default_allocator(), rec, &bytes, &size, &err), SL_OK);
    sl_occ_replay_report r;
    if (sl_occ_replay(rec, SL_RASTER_ISA_SCALAR, NULL, &r, &err) != SL_OK)
        fail_msg("%s", err.message);
    assert_int_equal(r.mismatches, 0);
    assert_true(r.batches > 0 && r.queries > 0);

    /* seeded single-bit and single-byte damage anywhere in the file: refused, never "ok" */
    sl_rng rng;
    sl_rng_seed(&rng, 12, 5);
    int flips = getenv("SL_SANITIZED") ? 100 : 300, accepted = 0;
    for (int i = 0; i < flips; i++) {
        size_t at = i < 16 ? size - 1 - (size_t)i : sl_rng_below(&rng, (uint32_t)size); /* the checksum too */
        uint8_t old = bytes[at];
        bytes[at] ^= i % 2 ? (uint8_t)(1u << sl_rng_below(&rng, 8)) : (uint8_t)(1 + sl_rng_below(&rng, 255));
        write_bytes(bad, bytes, size);
        sl_status st = sl_occ_replay(bad, SL_RASTER_ISA_SCALAR, NULL, &r, &err);
        if (st == SL_OK) {
            print_message("byte %zu: 0x%02x -> 0x%02x replays as ok (%u mismatches)\n", at, old, bytes[at],
                          r.mismatches);
            accepted++;
        } else {
            /* the file, an offset and a reason */
            assert_non_null(strstr(err.message, bad));
            assert_non_null(strstr(err.message, "offset "));
        }
        bytes[at] = old;
    }
    if (accepted)
        fail_msg("%d of %d damaged copies were accepted", accepted, flips);
    /* damage past the header names the checksum */
    bytes[size / 2] ^= 0x10;
    write_bytes(bad, bytes, size);
    assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_SCALAR, NULL, &r, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "checksum mismatch"));
    bytes[size / 2] ^= 0x10;
    /* a truncated file, a file without its checksum */
    write_bytes(bad, bytes, size - 8);
    assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_SCALAR, NULL, &r, &err), SL_ERROR_FORMAT);
    write_bytes(bad, bytes, 40);
    assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_SCALAR, NULL, &r, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "truncated"));
    /* a version 1 file (no checksum) is refused with the advice to record again */
    uint32_t v1 = 1;
    memcpy(bytes + 8, &v1, 4);
    write_bytes(bad, bytes, size - 8);
    assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_SCALAR, NULL, &r, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "version 1"));
    assert_non_null(strstr(err.message, "record the frame again"));
    free(bytes);
    unlink(bad);
    unlink(rec);
    rmdir(dir);
}

/* With a valid checksum, a changed recorded answer is not damage but a disagreement: the replay
 * succeeds and reports the mismatch (what `occlusion replay` turns into exit 1). */
static void test_resealed_answer_mismatches(void **state)
{
    (void)state;
    char dir[] = "/tmp/sl_occrec_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char rec[300];
    snprintf(rec, sizeof rec, "%s/f.rec", dir);
    record("hzb", rec);
    sl_error err;
    uint8_t *bytes;
    size_t size;
    assert_int_equal(sl_file_read_all(sl_default_allocator(), rec, &bytes, &size, &err), SL_OK);
    /* the last record is a query whose answer is its last u32, just before the checksum */
    uint32_t answer;
    memcpy(&answer, bytes + size - 12, 4);
    assert_true(answer <= 2);
    answer = answer == 1 ? 0 : 1;
    memcpy(bytes + size - 12, &answer, 4);
    uint64_t sum = sl_hash64(bytes, size - 8, 0);
    memcpy(bytes + size - 8, &sum, 8);
    sl_occ_replay_report r;
    if (sl_occ_replay_memory(bytes, size, "mem.rec", SL_RASTER_ISA_SCALAR, NULL, &r, &err) != SL_OK)
        fail_msg("%s", err.message);
    assert_int_equal(r.mismatches, 1);
    free(bytes);
    unlink(rec);
    rmdir(dir);
}

/* A fuzzer's recording (issue 12, fuzz/fuzz_occrec.c; kept as a seed) whose first batch reaches
 * the general kernel of the AVX2 and AVX-512 paths with a tile range starting at column 2: the
 * kernel formed the pointer zcol - tx0 outside its column-depth array (UBSan under clang: "index -2
 * out of bounds for type 'float[264]'"). The file is valid (checksum, fields): it must replay
 * cleanly, with the recorded answers and the same depth on every path. */
static void test_fuzz_seed_replays_on_every_path(void **state)
{
    (void)state;
    const char *seed = SL_SOURCE_DIR "/fuzz/seeds/occrec/raster_zcol_base.rec";
    const sl_raster_isa isas[] = {SL_RASTER_ISA_SCALAR, SL_RASTER_ISA_SSE41, SL_RASTER_ISA_AVX2,
                                  SL_RASTER_ISA_AVX512, SL_RASTER_ISA_AUTO};
    uint64_t ref = 0;
    for (size_t i = 0; i < sizeof isas / sizeof isas[0]; i++) {
        if (!sl_raster_isa_available(isas[i]))
            continue;
        sl_occ_replay_report r;
        sl_error err;
        if (sl_occ_replay(seed, isas[i], NULL, &r, &err) != SL_OK)
            fail_msg("%s: %s", sl_raster_isa_name(isas[i]), err.message);
        assert_int_equal(r.width, 129);
        assert_int_equal(r.height, 202);
        assert_int_equal(r.batches, 1);
        assert_int_equal(r.queries, 2);
        assert_int_equal(r.mismatches, 0);
        if (i == 0)
            ref = r.depth_hash;
        else if (r.depth_hash != ref)
            fail_msg("%s: depth hash %016llx, scalar %016llx", sl_raster_isa_name(isas[i]),
                     (unsigned long long)r.depth_hash, (unsigned long long)ref);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_flipped_bytes_refused),
        cmocka_unit_test(test_resealed_answer_mismatches),
        cmocka_unit_test(test_fuzz_seed_replays_on_every_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The version policy (docs/versions.md):
 *  - the library reports its version (sl_version, sl_version_string), which is the headers'
 *    SL_VERSION_* and CMake's project version, and `sightline --version` prints it;
 *  - every shared library in the build has a SONAME carrying the major version;
 *  - every file format carries a version, and a reader given a header of another major version
 *    refuses it with a message that says what to do: a newer one needs a newer Sightline, an older
 *    one is converted (baked or recorded again) as the message says. One header per format:
 *    .slscene, .slpvs, the bake's checkpoint journal, occlusion recordings (.rec), path files. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <glob.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/bytes.h"
#include "core/sl_core.h"
#include "cull/occlusion_debug.h"
#include "region/pvs_internal.h"
#include "sightline/core.h"
#include "sightline/path.h"
#include "sightline/pvs.h"
#include "sightline/slscene.h"


static void expect_message(sl_status got, sl_status want, const sl_error *err, const char *a, const char *b)
{
    if (got != want || !strstr(err->message, a) || (b && !strstr(err->message, b)))
        fail_msg("status %d (want %d), message '%s' (want '%s'%s%s)", (int)got, (int)want, err->message, a,
                 b ? " and " : "", b ? b : "");
}

/* ---- the library's version ---- */

static void test_library_version(void **state)
{
    (void)state;
    uint32_t major = 99, minor = 99, patch = 99;
    sl_version(&major, &minor, &patch);
    assert_int_equal(major, SL_VERSION_MAJOR);
    assert_int_equal(minor, SL_VERSION_MINOR);
    assert_int_equal(patch, SL_VERSION_PATCH);
    sl_version(NULL, NULL, NULL);
    char want[64];
    snprintf(want, sizeof want, "%u.%u.%u", major, minor, patch);
    assert_string_equal(sl_version_string(), want);

    /* CMake's project(sightline VERSION x.y.z) */
    FILE *f = fopen(SL_SOURCE_DIR "/CMakeLists.txt", "r");
    assert_non_null(f);
    char line[512];
    bool found = false;
    while (fgets(line, sizeof line, f)) {
        unsigned a, b, c;
        if (sscanf(line, "project(sightline VERSION %u.%u.%u", &a, &b, &c) == 3) {
            found = true;
            if (a != major || b != minor || c != patch)
                fail_msg("CMakeLists.txt says %u.%u.%u, sl_version %s", a, b, c, want);
        }
    }
    fclose(f);
    assert_true(found);

    /* sightline --version */
    const char *cli = getenv("SL_SIGHTLINE");
    if (!cli)
        cli = SL_BINARY_DIR "/sightline";
    char cmd[4200], out[256] = "";
    snprintf(cmd, sizeof cmd, "'%s' --version", cli);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    if (!fgets(out, sizeof out, p))
        out[0] = 0;
    assert_int_equal(pclose(p), 0);
    char expect[96];
    snprintf(expect, sizeof expect, "sightline %s\n", want);
    assert_string_equal(out, expect);
}

/* Every shared library the build made (libsightline.so, and any other lib*.so beside it) has a
 * SONAME lib<name>.so.<major>. */
static void test_soname(void **state)
{
    (void)state;
    glob_t g;
    int rc = glob(SL_BINARY_DIR "/lib*.so", 0, NULL, &g);
    if (rc != 0)
        fail_msg("no shared library in %s (build the sightline target first)", SL_BINARY_DIR);
    bool main_lib = false;
    for (size_t i = 0; i < g.gl_pathc; i++) {
        const char *lib = g.gl_pathv[i];
        const char *base = strrchr(lib, '/') + 1;
        main_lib |= !strcmp(base, "libsightline.so");
        char cmd[4200], line[512], soname[256] = "";
        snprintf(cmd, sizeof cmd, "readelf -d '%s'", lib);
        FILE *p = popen(cmd, "r");
        assert_non_null(p);
        while (fgets(line, sizeof line, p)) {
            const char *s = strstr(line, "Library soname: [");
            if (s) {
                snprintf(soname, sizeof soname, "%s", s + 17);
                soname[strcspn(soname, "]")] = 0;
            }
        }
        assert_int_equal(pclose(p), 0);
        char want[300];
        snprintf(want, sizeof want, "%s.%d", base, SL_VERSION_MAJOR);
        if (strcmp(soname, want))
            fail_msg("%s: SONAME '%s', expected '%s'", lib, soname, want);
    }
    globfree(&g);
    assert_true(main_lib);
}

/* ---- the file formats ---- */

static void test_slscene(void **state)
{
    (void)state;
    uint8_t h[256];
    memset(h, 0, sizeof h);
    memcpy(h, "SLSCENE", 8);
    sl_scene s = NULL;
    sl_error err;
    wr32(h + 8, 2); /* a newer major version */
    expect_message(sl_scene_load_memory(h, sizeof h, "new.slscene", NULL, &s, &err), SL_ERROR_UNSUPPORTED, &err,
                   "format version 2.0 is newer than this reader", "upgrade Sightline");
    wr32(h + 8, 0); /* before the first */
    expect_message(sl_scene_load_memory(h, sizeof h, "old.slscene", NULL, &s, &err), SL_ERROR_FORMAT, &err,
                   "format version 0.0 does not exist", NULL);
    assert_null(s);
}

static void test_slpvs(void **state)
{
    (void)state;
    uint8_t h[256];
    memset(h, 0, sizeof h);
    memcpy(h, "SLPVS\0\0", 8);
    sl_pvs p = NULL;
    sl_error err;
    wr32(h + 8, 2);
    expect_message(sl_pvs_load_memory(h, sizeof h, "new.slpvs", NULL, &p, &err), SL_ERROR_UNSUPPORTED, &err,
                   "format version 2.0 is newer than this reader", "upgrade Sightline");
    wr32(h + 8, 0);
    expect_message(sl_pvs_load_memory(h, sizeof h, "old.slpvs", NULL, &p, &err), SL_ERROR_FORMAT, &err,
                   "format version 0.0 does not exist", NULL);
    assert_null(p);
    /* 1.0 files load; their older scene key is refused by sl_pvs_check_scene with the command that
     * bakes them again (tests/test_scene_key.c) */
}

static void test_journal(void **state)
{
    (void)state;
    uint8_t h[128];
    memset(h, 0, sizeof h);
    memcpy(h, "SLPVSCKP", 8);
    size_t valid;
    uint32_t resumed;
    sl_error err;
    wr32(h + 8, 1);
    expect_message(sl_bake_journal_check(h, sizeof h, 4, 4, 0, NULL, &valid, &resumed, &err), SL_ERROR_FORMAT, &err,
                   "journal version 1", "bake it again");
    wr32(h + 8, 3);
    expect_message(sl_bake_journal_check(h, sizeof h, 4, 4, 0, NULL, &valid, &resumed, &err), SL_ERROR_FORMAT, &err,
                   "journal version 3", "written by a newer Sightline");
}

static void test_recording(void **state)
{
    (void)state;
    uint8_t h[128];
    memset(h, 0, sizeof h);
    memcpy(h, "SLOCCREC", 8);
    sl_occ_replay_report r;
    sl_error err;
    wr32(h + 8, 1);
    expect_message(sl_occ_replay_memory(h, sizeof h, "old.rec", SL_RASTER_ISA_SCALAR, NULL, &r, &err),
                   SL_ERROR_UNSUPPORTED, &err, "version 1", "record the frame again");
    wr32(h + 8, 3);
    expect_message(sl_occ_replay_memory(h, sizeof h, "new.rec", SL_RASTER_ISA_SCALAR, NULL, &r, &err),
                   SL_ERROR_UNSUPPORTED, &err, "version 3", "a newer Sightline wrote it");
}

static void test_path(void **state)
{
    (void)state;
    static const char text[] = "# sightline-path 2\n";
    sl_path p = NULL;
    sl_error err;
    expect_message(sl_path_parse(text, sizeof text - 1, "new.txt", NULL, &p, &err), SL_ERROR_UNSUPPORTED, &err,
                   "path format version '2' is not supported", "needs the newer Sightline");
    assert_null(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_library_version), cmocka_unit_test(test_soname), cmocka_unit_test(test_slscene),
        cmocka_unit_test(test_slpvs),           cmocka_unit_test(test_journal), cmocka_unit_test(test_recording),
        cmocka_unit_test(test_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

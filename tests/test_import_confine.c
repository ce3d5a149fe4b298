/* The assimp import path treats a model as untrusted input (issue 12 §4): the references inside
 * it (glTF buffers, OBJ material libraries, ...) resolve only inside the model's own folder unless
 * sl_import_options.allow_external allows more; refusals name the reference and the folder and
 * never echo the content of the file they point at; references are opened as regular files only
 * and within the size limit. Fixtures: tests/data/confine/model/ (the models) and
 * tests/data/confine/secret/ (what they must not reach: a triangle 7 times larger than the
 * model's own, a material library holding marker text and an escape sequence). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/escape.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"
#include "support/counting_alloc.h"

#define CONFINE SL_SOURCE_DIR "/tests/data/confine/"
#define MODEL CONFINE "model/"
#define SECRET CONFINE "secret/"

const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:libassimp.so\n"; }

static char *make_tmpdir(void)
{
    char *dir = malloc(512);
    assert_non_null(dir);
    snprintf(dir, 512, "%s/test_import_confine.XXXXXX", SL_BINARY_DIR);
    assert_non_null(mkdtemp(dir));
    return dir;
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, strlen(text), f), strlen(text));
    assert_int_equal(fclose(f), 0);
}

/* A one-triangle glTF whose buffer (byte_length bytes, the positions first) is at uri. */
static void write_gltf(const char *path, const char *uri, unsigned byte_length)
{
    char text[2048];
    snprintf(text, sizeof text,
             "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
             "\"min\":[0,0,0],\"max\":[1,1,0]}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
             "\"buffers\":[{\"uri\":\"%s\",\"byteLength\":%u}]}\n",
             uri, byte_length);
    write_text(path, text);
}

static void write_triangle_bin(const char *path, float size, unsigned byte_length)
{
    float v[9] = {0, 0, 0, size, 0, 0, 0, size, 0};
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(v, sizeof v, 1, f), 1);
    for (unsigned i = sizeof v; i < byte_length; i++)
        fputc(0, f);
    assert_int_equal(fclose(f), 0);
}

/* Import with the counting allocator; returns the status, the scene's largest bound coordinate in
 * *extent (when it imported) and the message in err. */
static sl_status import(const char *path, const char *const *allow, uint32_t allow_count, uint64_t max_bytes, float *extent,
                        sl_error *err)
{
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_import_options opt = sl_import_defaults();
    opt.allow_external = allow;
    opt.allow_external_count = allow_count;
    opt.max_file_bytes = max_bytes;
    sl_scene s = NULL;
    memset(err, 0, sizeof *err);
    sl_status st = sl_import_assimp(path, &opt, &a, &s, err);
    if (st == SL_OK) {
        sl_aabb b = sl_scene_bounds(s);
        *extent = b.max.x > b.max.z ? b.max.x : b.max.z;
        sl_scene_destroy(s);
    } else {
        assert_null(s);
    }
    assert_int_equal(cnt.live, 0);
    return st;
}

/* Nothing of the secret files' content in a message. */
static void no_content(const char *message)
{
    if (strstr(message, "SECRET") || strstr(message, "root:x") || strchr(message, '\x1b') || strstr(message, "Kd 0 0 1"))
        fail_msg("the message echoes file content: '%s'", message);
}

static void expect_refused(const char *path, const char *reference, const char *const *allow, uint32_t allow_count)
{
    sl_error err;
    float extent = 0;
    sl_status st = import(path, allow, allow_count, 0, &extent, &err);
    if (st == SL_OK)
        fail_msg("%s: imported (extent %g) although '%s' leaves the folder", path, (double)extent, reference);
    assert_int_equal(st, SL_ERROR_FORMAT);
    no_content(err.message);
    if (!strstr(err.message, reference) || !strstr(err.message, "outside the model's folder") || !strstr(err.message, "refused"))
        fail_msg("%s: the message does not name the reference '%s' and the folder: '%s'", path, reference, err.message);
}

/* References inside the model's folder work as before. */
static void test_inside(void **state)
{
    (void)state;
    sl_error err;
    float extent = 0;
    assert_int_equal(import(MODEL "inside.gltf", NULL, 0, 0, &extent, &err), SL_OK);
    assert_true(extent > 0.99f && extent < 1.01f);
    assert_int_equal(import(MODEL "inside.obj", NULL, 0, 0, &extent, &err), SL_OK);
    /* the material library inside the folder was read: the object is red */
    sl_scene s;
    assert_int_equal(sl_import_assimp(MODEL "inside.obj", NULL, NULL, &s, &err), SL_OK);
    assert_int_equal(sl_scene_object(s, 0).color, 0xff0000ffu);
    sl_scene_destroy(s);
}

/* '../' references are refused, in glTF buffers and OBJ material libraries alike (the OBJ one
 * would only be a warning to assimp, which carries on with a default material). */
static void test_parent_refused(void **state)
{
    (void)state;
    expect_refused(MODEL "up_buffer.gltf", "../secret/tri.bin", NULL, 0);
    expect_refused(MODEL "up_mtllib.obj", "../secret/secret.mtl", NULL, 0);
    /* sl_scene_open (the CLI's path for info, export, path, pvs ...) goes the same way */
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_open(MODEL "up_buffer.gltf", NULL, NULL, &s, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "../secret/tri.bin"));
}

/* allow_external opens a folder or exactly one file, nothing more. */
static void test_allowed(void **state)
{
    (void)state;
    sl_error err;
    float extent = 0;
    const char *folder[] = {SECRET};
    assert_int_equal(import(MODEL "up_buffer.gltf", folder, 1, 0, &extent, &err), SL_OK);
    assert_true(extent > 6.99f && extent < 7.01f); /* the outside triangle was read */
    const char *folder_no_slash[] = {CONFINE "secret"};
    assert_int_equal(import(MODEL "up_buffer.gltf", folder_no_slash, 1, 0, &extent, &err), SL_OK);
    const char *file[] = {SECRET "secret.mtl"};
    assert_int_equal(import(MODEL "up_mtllib.obj", file, 1, 0, &extent, &err), SL_OK);
    /* a file allows only itself */
    expect_refused(MODEL "up_buffer.gltf", "../secret/tri.bin", file, 1);
    /* a folder named like a prefix of the secret one allows nothing in it */
    char *dir = make_tmpdir(), sibling[600], link[700];
    snprintf(sibling, sizeof sibling, "%s/secr", dir);
    assert_int_equal(mkdir(sibling, 0755), 0);
    const char *prefix[] = {sibling};
    expect_refused(MODEL "up_buffer.gltf", "../secret/tri.bin", prefix, 1);
    /* an allowed path that does not exist is a caller error */
    const char *missing[] = {CONFINE "no-such-folder"};
    assert_int_equal(import(MODEL "up_buffer.gltf", missing, 1, 0, &extent, &err), SL_ERROR_NOT_FOUND);
    assert_non_null(strstr(err.message, "no-such-folder"));
    const char *empty[] = {""};
    assert_int_equal(import(MODEL "inside.gltf", empty, 1, 0, &extent, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(import(MODEL "inside.gltf", NULL, 1, 0, &extent, &err), SL_ERROR_INVALID_ARGUMENT);
    rmdir(sibling);
    (void)link;
    rmdir(dir);
    free(dir);
}

/* Absolute references and symlinks that point out of the folder are refused too; a symlink that
 * stays inside is fine; the folder is the one the model was named in. */
static void test_symlinks_and_absolute(void **state)
{
    (void)state;
    char *dir = make_tmpdir(), path[700], target[700], ref[800];
    sl_error err;
    float extent = 0;

    /* link.bin -> the secret triangle */
    snprintf(path, sizeof path, "%s/link.bin", dir);
    assert_int_equal(symlink(SECRET "tri.bin", path), 0);
    snprintf(path, sizeof path, "%s/link.gltf", dir);
    write_gltf(path, "link.bin", 36);
    expect_refused(path, "link.bin", NULL, 0);

    /* an absolute URI: assimp's glTF reader puts the model's folder in front of it, so it names
     * no file; whichever way, it is not read */
    snprintf(path, sizeof path, "%s/absolute.gltf", dir);
    write_gltf(path, SECRET "tri.bin", 36);
    assert_int_equal(import(path, NULL, 0, 0, &extent, &err), SL_ERROR_FORMAT);
    no_content(err.message);
    /* the same for an OBJ material library (a missing one is only a warning to assimp): the
     * secret library's blue is not read */
    snprintf(path, sizeof path, "%s/absolute.obj", dir);
    write_text(path, "mtllib " SECRET "secret.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
    sl_scene s = NULL;
    if (sl_import_assimp(path, NULL, NULL, &s, &err) == SL_OK) {
        assert_int_not_equal(sl_scene_object(s, 0).color, 0x0000ffffu);
        sl_scene_destroy(s);
    } else {
        no_content(err.message);
    }

    /* a symlinked folder inside pointing out */
    snprintf(target, sizeof target, "%s/out", dir);
    assert_int_equal(symlink(CONFINE "secret", target), 0);
    snprintf(path, sizeof path, "%s/via_dir.gltf", dir);
    write_gltf(path, "out/tri.bin", 36);
    expect_refused(path, "out/tri.bin", NULL, 0);

    /* a symlink to a file inside the folder is fine */
    snprintf(target, sizeof target, "%s/real.bin", dir);
    write_triangle_bin(target, 2, 36);
    snprintf(path, sizeof path, "%s/alias.bin", dir);
    assert_int_equal(symlink("real.bin", path), 0);
    snprintf(path, sizeof path, "%s/alias.gltf", dir);
    write_gltf(path, "alias.bin", 36);
    assert_int_equal(import(path, NULL, 0, 0, &extent, &err), SL_OK);
    assert_true(extent > 1.99f && extent < 2.01f);

    /* the model itself reached through a symlink from another folder: its references resolve
     * against the folder it was named in (where assimp looks for them), which holds no real.bin */
    snprintf(path, sizeof path, "%s/sub", dir);
    assert_int_equal(mkdir(path, 0755), 0);
    snprintf(ref, sizeof ref, "%s/sub/real.gltf", dir);
    snprintf(path, sizeof path, "%s/real.gltf", dir);
    write_gltf(path, "../real.bin", 36);
    assert_int_equal(symlink(path, ref), 0);
    expect_refused(ref, "../real.bin", NULL, 0);

    const char *names[] = {"link.bin", "link.gltf", "absolute.gltf", "absolute.obj", "out", "via_dir.gltf", "real.bin", "alias.bin",
                           "alias.gltf", "sub/real.gltf", "sub", "real.gltf"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        if (unlink(path) != 0)
            rmdir(path);
    }
    assert_int_equal(rmdir(dir), 0);
    free(dir);
}

/* A FIFO named as a reference is refused at once (opened non-blocking, regular files only), and a
 * reference larger than the size limit is refused with the numbers. */
static void test_fifo_and_size(void **state)
{
    (void)state;
    char *dir = make_tmpdir(), path[700];
    sl_error err;
    float extent = 0;
    snprintf(path, sizeof path, "%s/pipe.bin", dir);
    assert_int_equal(mkfifo(path, 0600), 0);
    snprintf(path, sizeof path, "%s/pipe.gltf", dir);
    write_gltf(path, "pipe.bin", 36);
    assert_int_equal(import(path, NULL, 0, 0, &extent, &err), SL_ERROR_FORMAT);
    if (!strstr(err.message, "pipe.bin") || !strstr(err.message, "not a regular file"))
        fail_msg("unexpected message '%s'", err.message);

    snprintf(path, sizeof path, "%s/big.bin", dir);
    write_triangle_bin(path, 1, 5000);
    snprintf(path, sizeof path, "%s/big.gltf", dir);
    write_gltf(path, "big.bin", 5000);
    assert_int_equal(import(path, NULL, 0, 0, &extent, &err), SL_OK);
    assert_int_equal(import(path, NULL, 0, 4000, &extent, &err), SL_ERROR_LIMIT);
    if (!strstr(err.message, "big.bin") || !strstr(err.message, "5000 bytes") || !strstr(err.message, "4000"))
        fail_msg("unexpected message '%s'", err.message);
    /* the model itself is held to the limit too */
    assert_int_equal(import(path, NULL, 0, 100, &extent, &err), SL_ERROR_LIMIT);

    const char *names[] = {"pipe.bin", "pipe.gltf", "big.bin", "big.gltf"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        unlink(path);
    }
    assert_int_equal(rmdir(dir), 0);
    free(dir);
}

/* An OBJ's material library must be text: one with NUL bytes crashed assimp 5.2's MTL reader
 * (SIGSEGV; found by fuzz/fuzz_assimp.c). */
static void test_binary_material_library(void **state)
{
    (void)state;
    sl_error err;
    float extent = 0;
    assert_int_equal(import(MODEL "nul_mtllib.obj", NULL, 0, 0, &extent, &err), SL_ERROR_FORMAT);
    if (!strstr(err.message, "'nul.mtl' holds NUL bytes"))
        fail_msg("unexpected message '%s'", err.message);
}

/* What reaches a message or a listing from a file: C-style escapes for control bytes, C1
 * controls, bytes that are not UTF-8 and backslashes; well-formed UTF-8 unchanged; cut short with
 * "...". */
static void test_escape_text(void **state)
{
    (void)state;
    char buf[64];
    assert_string_equal(sl_escape_text("maps/a\x1b[2Jb\n.bsp", 100, buf, sizeof buf), "maps/a\\x1b[2Jb\\x0a.bsp");
    assert_string_equal(sl_escape_text("caf\xc3\xa9 \xe2\x82\xac", 100, buf, sizeof buf), "caf\xc3\xa9 \xe2\x82\xac");
    assert_string_equal(sl_escape_text("c1\xc2\x9b del\x7f", 100, buf, sizeof buf), "c1\\xc2\\x9b del\\x7f");
    assert_string_equal(sl_escape_text("bad\xff\xfe over\xc0\xaf sur\xed\xa0\x80", 100, buf, sizeof buf),
                        "bad\\xff\\xfe over\\xc0\\xaf sur\\xed\\xa0\\x80");
    assert_string_equal(sl_escape_text("a\\b", 100, buf, sizeof buf), "a\\\\b");
    assert_string_equal(sl_escape_text("abcdefgh", 4, buf, sizeof buf), "abcd...");
    assert_string_equal(sl_escape_text("truncated \xe2\x82", 100, buf, sizeof buf), "truncated \\xe2\\x82");
    /* the buffer bounds the output, never splitting an escape */
    char small[12];
    sl_escape_text("\x01\x02\x03\x04\x05", 100, small, sizeof small);
    assert_string_equal(small, "\\x01\\x02...");
    assert_int_equal(sl_utf8_sequence((const unsigned char *)"\xf0\x9f\x98\x80", 4), 4);
    assert_int_equal(sl_utf8_sequence((const unsigned char *)"\xf4\x90\x80\x80", 4), 0); /* past U+10FFFF */
}

/* A relative model path: its folder is the current directory's. */
static void test_relative_path(void **state)
{
    (void)state;
    char cwd[4096];
    assert_non_null(getcwd(cwd, sizeof cwd));
    assert_int_equal(chdir(MODEL), 0);
    sl_error err;
    float extent = 0;
    sl_status inside = import("inside.gltf", NULL, 0, 0, &extent, &err);
    sl_status up = import("up_buffer.gltf", NULL, 0, 0, &extent, &err);
    char message[sizeof err.message];
    memcpy(message, err.message, sizeof message);
    assert_int_equal(chdir(cwd), 0);
    assert_int_equal(inside, SL_OK);
    assert_int_equal(up, SL_ERROR_FORMAT);
    no_content(message);
    assert_non_null(strstr(message, "../secret/tri.bin"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_inside),
        cmocka_unit_test(test_parent_refused),
        cmocka_unit_test(test_allowed),
        cmocka_unit_test(test_symlinks_and_absolute),
        cmocka_unit_test(test_fifo_and_size),
        cmocka_unit_test(test_relative_path),
        cmocka_unit_test(test_binary_material_library),
        cmocka_unit_test(test_escape_text),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* libFuzzer target for the assimp import path (sl_import_assimp): the confined IO system, its
 * limits, the PLY header check, and what Sightline does with the scene assimp hands back.
 *
 * Input: the first byte picks the format (its value mod 5: OBJ, PLY, glTF, STL, OFF); the rest is
 * the model, written to a private temporary folder as model.<ext>. When the model holds the
 * line "--8<--", what follows it is written as side.bin beside the model instead (the seeds' glTF
 * names it as its buffer, the OBJ as its material library), so that references inside the folder
 * are followed. References out of the folder are refused by the IO system like in the CLI; each
 * file is capped at 2 MiB. assimp's own leaks on some hostile inputs are not ours: see
 * __lsan_default_suppressions below and tests/lsan.supp.
 *
 * The import runs as the CLI runs it: our checks (options, file kind and size, the PLY header)
 * here, assimp and the conversion in a child process (src/import/import_isolate.c), whose
 * scene comes back through the .slscene reader. assimp 5.2 is not instrumented and reads past
 * its buffers on some inputs (found here: the CI run of 2026-12-01 stopped on a corrupted heap
 * chunk inside assimp); in the child that costs the child only. What runs in the child is not
 * seen by this fuzzer's coverage or sanitizers: tests/test_import_isolate.c runs the same
 * conversion in process under the sanitizers, on the test models. */
#include "sightline/import.h"
#include "sightline/scene.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
const char *__lsan_default_suppressions(void);
/* assimp is built without frame pointers: a leak of its C++ objects may end its stack in
 * operator new (libstdc++, which only assimp uses here) before reaching libassimp itself */
const char *__lsan_default_suppressions(void) { return "leak:libassimp.so\nleak:libstdc++.so\n"; }
/* ... and without a "Suppressions used" table after every input that leaked inside assimp */
const char *__lsan_default_options(void);
const char *__lsan_default_options(void) { return "print_suppressions=0"; }

static char folder[64];

static void remove_folder(void)
{
    static const char *names[] = {"model.obj", "model.ply", "model.gltf", "model.stl", "model.off", "side.bin"};
    char path[128];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", folder, names[i]);
        unlink(path);
    }
    rmdir(folder);
}

static int write_file(const char *path, const uint8_t *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return -1;
    size_t w = n ? fwrite(p, 1, n, f) : 0;
    return fclose(f) == 0 && w == n ? 0 : -1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *ext[] = {"obj", "ply", "gltf", "stl", "off"};
    if (!folder[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(folder, sizeof folder, "%.40s/sl_fuzz_assimp.XXXXXX", tmp && tmp[0] && strlen(tmp) < 40 ? tmp : "/tmp");
        if (!mkdtemp(folder))
            abort();
        atexit(remove_folder);
    }
    if (size < 1)
        return 0;
    const char *e = ext[data[0] % 5];
    const uint8_t *model = data + 1;
    size_t model_size = size - 1, side_size = 0;
    const uint8_t *side = NULL;
    static const char cut[] = "\n--8<--\n";
    for (size_t i = 0; i + sizeof cut - 1 <= model_size; i++)
        if (!memcmp(model + i, cut, sizeof cut - 1)) {
            side = model + i + sizeof cut - 1;
            side_size = model_size - i - (sizeof cut - 1);
            model_size = i + 1; /* keep the newline */
            break;
        }
    char path[128], side_path[128];
    snprintf(path, sizeof path, "%s/model.%s", folder, e);
    snprintf(side_path, sizeof side_path, "%s/side.bin", folder);
    unlink(side_path);
    if (write_file(path, model, model_size) != 0 || (side && write_file(side_path, side, side_size) != 0))
        abort();

    sl_import_options opt = sl_import_defaults();
    opt.max_file_bytes = (uint64_t)2 << 20;
    opt.timeout_ms = 20000; /* a child that loops is stopped well before libFuzzer's -timeout */
    opt.split_triangles = data[0] >= 128 ? 64 : 0; /* the splitter on half the inputs */
    sl_scene scene;
    sl_error err;
    if (sl_import_assimp(path, &opt, NULL, &scene, &err) == SL_OK) {
        /* touch what came back */
        sl_scene_stats st;
        sl_scene_get_stats(scene, &st);
        if (st.object_count == 0 || st.triangle_count == 0)
            abort(); /* an import succeeds only with triangles */
        sl_scene_destroy(scene);
    } else if (!err.message[0]) {
        abort(); /* every failure says why */
    } else {
        /* messages are escaped: no control byte from the file may reach them */
        for (const char *p = err.message; *p; p++)
            if ((unsigned char)*p < 0x20 || *p == 0x7f)
                abort();
    }
    unlink(path);
    return 0;
}

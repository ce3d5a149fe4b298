/* libFuzzer target: the Quake III map reader on arbitrary bytes. The triangle budget is kept
 * small (sl_q3bsp_import_memory_limited is what sl_import_q3bsp_memory calls with the default
 * budget) so that a tiny input cannot ask for gigabytes of tessellated patches.
 *
 * With SL_FUZZ_CLI_LIMITS=1 in the environment the budget is the command line's
 * (SL_Q3_MAX_TRIANGLES; the importer's own bound relative to the file size still applies), so that
 * the large-allocation paths are fuzzed too; scripts/fuzz.sh runs it so once per run. */
#include "import/pk3.h"

#include <stdint.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int cli = -1;
    if (cli < 0) {
        const char *e = getenv("SL_FUZZ_CLI_LIMITS");
        cli = e && e[0] == '1';
    }
    sl_scene scene;
    sl_error err;
    uint64_t max_tris = cli ? SL_Q3_MAX_TRIANGLES : (uint64_t)1 << 20;
    if (sl_q3bsp_import_memory_limited(data, size, "fuzz.bsp", NULL, max_tris, NULL, &scene, &err) != SL_OK)
        return 0;
    /* walk the tree from a few points and read every object back */
    sl_aabb box = sl_scene_bounds(scene);
    sl_vec3 points[3] = {box.min, box.max, {0, 0, 0}};
    for (int i = 0; i < 3; i++)
        (void)sl_scene_bsp_find_leaf(scene, points[i]);
    for (uint32_t o = 0; o < sl_scene_object_count(scene); o++)
        (void)sl_scene_object(scene, o);
    sl_scene_destroy(scene);
    return 0;
}

/* libFuzzer target: the occlusion recording reader and replayer (sl_occ_replay_memory, what
 * `sightline occlusion replay` runs). Each input is replayed as it is (the checksum refuses
 * nearly every mutation, which tests the magic, version and checksum checks) and again with its
 * trailing XXH3 checksum recomputed, so that mutations reach the record validation and the
 * rasterizer behind it. Recordings of more than 256x256 pixels are skipped on the second pass:
 * the replay clears and renders the whole buffer, and big ones would only slow the fuzzer. */
#include "core/sl_core.h"
#include "cull/occlusion_debug.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sl_occ_replay_report rep;
    sl_error err;
    uint32_t w = 0, h = 0;
    if (size >= 20) {
        memcpy(&w, data + 12, 4);
        memcpy(&h, data + 16, 4);
    }
    bool small = (uint64_t)w * h <= 256u * 256u;
    if (small)
        (void)sl_occ_replay_memory(data, size, "fuzz.rec", SL_RASTER_ISA_SCALAR, NULL, &rep, &err);
    if (size < 44 || !small)
        return 0;
    uint8_t *copy = malloc(size);
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    uint64_t sum = sl_hash64(copy, size - 8, 0);
    memcpy(copy + size - 8, &sum, 8);
    /* the best path too: the paths must agree, which the replay itself checks against the file */
    (void)sl_occ_replay_memory(copy, size, "fuzz.rec", SL_RASTER_ISA_AUTO, NULL, &rep, &err);
    free(copy);
    return 0;
}

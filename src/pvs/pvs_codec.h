/* Internal, run time (pvs layer): the .slpvs set codec and the zstd allocator bridge, shared by
 * the file reader and writer (pvs_file.c) and the bake drivers (region/pvs_build.c). */
#ifndef SL_PVS_CODEC_H
#define SL_PVS_CODEC_H

#include "sightline/pvs.h"
#include "core/sl_core.h"

#define ZSTD_STATIC_LINKING_ONLY /* ZSTD_customMem: zstd allocates through the handle's allocator */
#include <zstd.h>

/* ---- set encoding: a strictly ascending id list as LEB128 varints of the gaps ----
 * first value = id[0], then id[k] - id[k-1] - 1. At most 5 bytes per id. */
static inline size_t sl_pvs_encode(const uint32_t *ids, uint32_t n, uint8_t *out)
{
    size_t at = 0;
    uint32_t prev = 0;
    for (uint32_t k = 0; k < n; k++) {
        uint32_t v = k == 0 ? ids[0] : ids[k] - prev - 1;
        prev = ids[k];
        while (v >= 0x80) {
            out[at++] = (uint8_t)(v | 0x80);
            v >>= 7;
        }
        out[at++] = (uint8_t)v;
    }
    return at;
}

/* Decode exactly n ids from bytes [p, end); false when the stream is malformed, does not end
 * exactly at `end`, overflows, or yields an id >= limit. */
static inline bool sl_pvs_decode(const uint8_t *p, const uint8_t *end, uint32_t n, uint32_t limit, uint32_t *ids)
{
    uint64_t prev = 0;
    for (uint32_t k = 0; k < n; k++) {
        uint64_t v = 0;
        for (int shift = 0;; shift += 7) {
            if (p >= end || shift > 28)
                return false;
            uint8_t b = *p++;
            v |= (uint64_t)(b & 0x7f) << shift;
            if (!(b & 0x80))
                break;
        }
        uint64_t id = k == 0 ? v : prev + 1 + v;
        if (id >= limit)
            return false;
        ids[k] = (uint32_t)id;
        prev = id;
    }
    return p == end;
}

/* zstd allocation through an sl_allocator (the size is kept in front of each block). */
ZSTD_customMem sl_zstd_mem(const sl_allocator *a);

#endif

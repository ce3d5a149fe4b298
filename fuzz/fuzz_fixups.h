/* Checksum fix-ups shared by fuzz targets that load .slscene and .slpvs files: recomputing every
 * checksum lets the mutations reach the parsers behind them. Layouts: docs/slscene-format.md and
 * docs/pvs.md (header 64 bytes; section table entries with offset, size and XXH3 hash).
 * (fuzz_slscene.c and fuzz_slpvs.c carry their own copies of the same two functions.) */
#ifndef SL_FUZZ_FIXUPS_H
#define SL_FUZZ_FIXUPS_H

#include "core/sl_core.h"

#include <string.h>

enum { FX_HDR = 64, FX_COUNT = 24, FX_ENTRY_SIZE = 28, FX_TABLE = 32, FX_TABLE_HASH = 48, FX_HASH = 56 };
enum { FX_E_OFFSET = 16, FX_E_SIZE = 24, FX_E_HASH = 32 };

static inline uint32_t fx_get32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static inline uint64_t fx_get64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static inline void fx_put64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

/* The section table's entries, their hashes, the table hash and the header hash (both formats
 * share this layout); max_sections bounds the table as each reader does. */
static inline void fx_fix_table(uint8_t *f, size_t size, uint64_t max_sections)
{
    if (size < FX_HDR)
        return;
    uint64_t n = fx_get32(f + FX_COUNT), es = fx_get32(f + FX_ENTRY_SIZE), t = fx_get64(f + FX_TABLE);
    if (es >= 48 && es <= 4096 && n <= max_sections && t <= size && n * es <= size - t) {
        for (uint64_t i = 0; i < n; i++) {
            uint8_t *e = f + t + i * es;
            uint64_t off = fx_get64(e + FX_E_OFFSET), len = fx_get64(e + FX_E_SIZE);
            if (off <= size && len <= size - off)
                fx_put64(e + FX_E_HASH, sl_hash64(f + off, (size_t)len, 0));
        }
        fx_put64(f + FX_TABLE_HASH, sl_hash64(f + t, (size_t)(n * es), 0));
    }
    fx_put64(f + FX_HASH, sl_hash64(f, FX_HASH, 0));
}

static inline void fx_fix_slscene(uint8_t *f, size_t size) { fx_fix_table(f, size, 4096); }

/* The entry of section `tag` of a .slpvs, or NULL. */
static inline uint8_t *fx_slpvs_entry(uint8_t *f, size_t size, const char *tag)
{
    uint64_t n = fx_get32(f + FX_COUNT), es = fx_get32(f + FX_ENTRY_SIZE), t = fx_get64(f + FX_TABLE);
    if (es < 48 || es > 4096 || n > 64 || t > size || n * es > size - t)
        return NULL;
    for (uint64_t i = 0; i < n; i++)
        if (memcmp(f + t + i * es, tag, 4) == 0)
            return f + t + i * es;
    return NULL;
}

static inline void fx_fix_slpvs(uint8_t *f, size_t size)
{
    if (size < FX_HDR)
        return;
    /* per-block frame checksums first: they live inside BLKS, whose own checksum follows */
    uint8_t *blks = fx_slpvs_entry(f, size, "BLKS"), *data = fx_slpvs_entry(f, size, "DATA");
    if (blks && data) {
        uint64_t bo = fx_get64(blks + FX_E_OFFSET), bl = fx_get64(blks + FX_E_SIZE);
        uint64_t dof = fx_get64(data + FX_E_OFFSET), dl = fx_get64(data + FX_E_SIZE);
        if (bo <= size && bl <= size - bo && dof <= size && dl <= size - dof)
            for (uint64_t k = 0; k + 32 <= bl; k += 32) {
                uint8_t *r = f + bo + k;
                uint64_t off = fx_get64(r);
                uint32_t cs = fx_get32(r + 8);
                if (off <= dl && cs <= dl - off)
                    fx_put64(r + 16, sl_hash64(f + dof + off, cs, 0));
            }
    }
    fx_fix_table(f, size, 64);
}

#endif

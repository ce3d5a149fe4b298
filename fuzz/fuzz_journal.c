/* libFuzzer target: the bake checkpoint journal reader (src/region/pvs_build.c, reached through
 * sl_bake_journal_check, the internal entry point that runs the resume path's reader on bytes).
 *
 * The journal's header must match the bake it resumes (cell count, object count, bake key), so
 * the target takes those three from the input's own header (version 2: a description follows it) (bounded: at most 4096 cells and
 * 65536 objects) and reads the input three ways: as it is; with a header rebuilt to match (magic,
 * version, zeroed padding, header checksum), so mutations reach the records; and with every
 * record's checksum recomputed as well, so they reach the set decoder. The seeds
 * (fuzz/seeds/journal) are real version-2 journals of small bakes; their README says how they were
 * made, and test_bake_files checks that they still read back whole. */
#include "core/sl_core.h"
#include "region/pvs_internal.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static uint32_t get32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t get64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static void put32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static void put64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

/* The layout of pvs_build.c's journal: 64-byte header, then records of a 24-byte head
 * (tag 'CELL', cell, count, bytes, XXH3 of the 16 bytes before it and the payload) and payload. */
enum { J_HEADER = 64, J_RECORD = 24 };
#define J_TAG 0x4c4c4543u

/* version 2: u32 description length at 20, the key's parts at 32..56, and the checksum at 56 over
 * the header's first 56 bytes then the description that follows the header */
static uint32_t desc_length(const uint8_t *f, size_t size)
{
    uint32_t d = get32(f + 20) % 4097;
    return d > size - J_HEADER ? (uint32_t)(size - J_HEADER) : d;
}

static void fix_header(uint8_t *f, size_t size, uint32_t cells, uint32_t objects, uint64_t key)
{
    uint32_t d = desc_length(f, size);
    uint8_t parts[24];
    memcpy(parts, f + 32, 24);
    memset(f, 0, J_HEADER);
    memcpy(f, "SLPVSCKP", 8);
    put32(f + 8, 2);
    put32(f + 12, cells);
    put32(f + 16, objects);
    put32(f + 20, d);
    put64(f + 24, key);
    memcpy(f + 32, parts, 24);
    put64(f + 56, sl_hash64(f + J_HEADER, d, sl_hash64(f, 56, 0)));
}

static void fix_records(uint8_t *f, size_t size)
{
    size_t at = J_HEADER + desc_length(f, size);
    while (size - at >= J_RECORD) {
        uint8_t *r = f + at;
        uint32_t bytes = get32(r + 12);
        if (bytes > size - at - J_RECORD)
            break;
        put32(r, J_TAG);
        uint64_t h = sl_hash64(r, 16, 0);
        put64(r + 16, sl_hash64(r + J_RECORD, bytes, h));
        at += J_RECORD + bytes;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint32_t cells = 1, objects = 1;
    uint64_t key = 0;
    if (size >= J_HEADER) {
        cells = get32(data + 12) % 4097;
        objects = get32(data + 16) % 65537;
        key = get64(data + 24);
    }
    size_t valid;
    uint32_t resumed;
    sl_error err;
    (void)sl_bake_journal_check(data, size, cells, objects, key, NULL, &valid, &resumed, &err);
    if (size < J_HEADER)
        return 0;
    uint8_t *copy = malloc(size);
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    fix_header(copy, size, cells, objects, key);
    if (sl_bake_journal_check(copy, size, cells, objects, key, NULL, &valid, &resumed, &err) == SL_OK &&
        (valid < J_HEADER || valid > size))
        abort(); /* the valid prefix lies inside the file and holds the header */
    fix_records(copy, size);
    if (sl_bake_journal_check(copy, size, cells, objects, key, NULL, &valid, &resumed, &err) == SL_OK &&
        (valid < J_HEADER || valid > size || resumed > cells))
        abort();
    free(copy);
    return 0;
}

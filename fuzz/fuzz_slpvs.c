/* libFuzzer target for the .slpvs reader (sl_pvs_load_memory, sl_pvs_cell_set, sl_pvs_verify).
 *
 * Each input is loaded twice: as it is (checksums reject nearly every mutation, which exercises the
 * header and section-table checks), and again with the section, table, header and per-block
 * checksums recomputed, so that mutations reach the record validation, the view-cell checks, the
 * zstd frames and the varint decoder behind them. A loaded PVS is decoded cell by cell, and its
 * motion regions (1.2) walked. */
#include "core/sl_core.h"
#include "sightline/pvs.h"

#include <stdlib.h>
#include <string.h>

/* The documented layout (docs/pvs.md). */
enum { HDR = 64, H_COUNT = 24, H_ENTRY_SIZE = 28, H_TABLE = 32, H_TABLE_HASH = 48, H_HASH = 56 };
enum { E_OFFSET = 16, E_SIZE = 24, E_HASH = 32 };

static uint32_t get32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t get64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static void put64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

/* The entry of section `tag`, or NULL. */
static uint8_t *entry(uint8_t *f, size_t size, const char *tag)
{
    uint64_t n = get32(f + H_COUNT), es = get32(f + H_ENTRY_SIZE), t = get64(f + H_TABLE);
    if (es < 48 || es > 4096 || n > 64 || t > size || n * es > size - t)
        return NULL;
    for (uint64_t i = 0; i < n; i++)
        if (memcmp(f + t + i * es, tag, 4) == 0)
            return f + t + i * es;
    return NULL;
}

static void fix_checksums(uint8_t *f, size_t size)
{
    if (size < HDR)
        return;
    /* per-block frame checksums first: they live inside BLKS, whose own checksum follows */
    uint8_t *blks = entry(f, size, "BLKS"), *data = entry(f, size, "DATA");
    if (blks && data) {
        uint64_t bo = get64(blks + E_OFFSET), bl = get64(blks + E_SIZE);
        uint64_t dof = get64(data + E_OFFSET), dl = get64(data + E_SIZE);
        if (bo <= size && bl <= size - bo && dof <= size && dl <= size - dof)
            for (uint64_t k = 0; k + 32 <= bl; k += 32) {
                uint8_t *r = f + bo + k;
                uint64_t off = get64(r);
                uint32_t cs = get32(r + 8);
                if (off <= dl && cs <= dl - off)
                    put64(r + 16, sl_hash64(f + dof + off, cs, 0));
            }
    }
    uint64_t n = get32(f + H_COUNT), es = get32(f + H_ENTRY_SIZE), t = get64(f + H_TABLE);
    if (es >= 48 && es <= 4096 && n <= 64 && t <= size && n * es <= size - t) {
        for (uint64_t i = 0; i < n; i++) {
            uint8_t *e = f + t + i * es;
            uint64_t off = get64(e + E_OFFSET), len = get64(e + E_SIZE);
            if (off <= size && len <= size - off)
                put64(e + E_HASH, sl_hash64(f + off, (size_t)len, 0));
        }
        put64(f + H_TABLE_HASH, sl_hash64(f + t, (size_t)(n * es), 0));
    }
    put64(f + H_HASH, sl_hash64(f, H_HASH, 0));
}

static void exercise(const uint8_t *data, size_t size)
{
    sl_pvs p;
    sl_error err;
    if (sl_pvs_load_memory(data, size, "fuzz", NULL, &p, &err) != SL_OK)
        return;
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    (void)sl_pvs_meta(p, "method");
    /* room for the largest set (bounded by the file's bytes), not for the stated object count */
    uint32_t cap = 0, n;
    for (uint32_t c = 0; c < in.cell_count; c++)
        cap = cap > sl_pvs_cell_count(p, c) ? cap : sl_pvs_cell_count(p, c);
    uint32_t *ids = malloc(((size_t)cap + 1) * sizeof *ids);
    for (uint32_t c = 0; ids && c < in.cell_count && c < 4096; c++)
        (void)sl_pvs_cell_set(p, c, ids, cap, &n, &err);
    (void)sl_viewcells_locate(sl_pvs_cells(p), NULL, (sl_vec3){0, 0, 1});
    if (ids) { /* the pvs culler's near-plane query over the file's cells */
        sl_aabb nb = {{-0.2f, -0.2f, 0.8f}, {0.2f, 0.2f, 1.2f}};
        bool cov;
        (void)sl_viewcells_overlap(sl_pvs_cells(p), NULL, &nb, ids, cap + 1, &cov);
    }
    /* the motion regions: every node's box walked down against each cell's row */
    const sl_pvs_region *nodes = sl_pvs_region_nodes(p);
    for (uint32_t c = 0; c < in.cell_count && c < 64; c++)
        for (uint32_t k = 0; k < sl_pvs_region_count(p) && k < 256; k++)
            (void)sl_pvs_region_box_visible(p, sl_pvs_region_row(p, c), &nodes[k].box);
    (void)sl_pvs_verify(p, &err);
    free(ids);
    sl_pvs_destroy(p);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    exercise(data, size);
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    fix_checksums(copy, size);
    exercise(copy, size);
    free(copy);
    return 0;
}

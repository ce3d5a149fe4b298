/* libFuzzer target: the .slscene and .slpvs readers on files, the way the command line opens
 * them (sl_scene_load: mapped, sections borrowed from the mapping; with no_mmap: read with
 * pread; sl_pvs_load: whatever the library's default for files is), which are other code paths
 * than the in-memory readers fuzz_slscene and fuzz_slpvs drive. Each input is written to a file
 * in $TMPDIR (default /tmp), as it is and with its checksums recomputed; the first byte picks the
 * format (even: .slscene, odd: .slpvs). A file and the same bytes in memory must get the same
 * answer: a loader that accepts one and refuses the other aborts the run. */
#include "fuzz_fixups.h"
#include "sightline/pvs.h"
#include "sightline/slscene.h"

#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char g_path[512];

static bool write_file(const uint8_t *data, size_t size)
{
    if (!g_path[0]) {
        const char *dir = getenv("TMPDIR");
        snprintf(g_path, sizeof g_path, "%s/sl_fuzz_mmap_%ld.bin", dir && dir[0] ? dir : "/tmp", (long)getpid());
    }
    FILE *f = fopen(g_path, "wb");
    if (!f)
        return false;
    bool ok = fwrite(data, 1, size, f) == size;
    return fclose(f) == 0 && ok;
}

static void scene_case(const uint8_t *data, size_t size)
{
    sl_scene s = NULL;
    sl_error err;
    sl_status mem = sl_scene_load_memory(data, size, "fuzz", NULL, &s, &err);
    if (s)
        sl_scene_destroy(s);
    if (!write_file(data, size))
        return;
    for (int no_mmap = 0; no_mmap < 2; no_mmap++) {
        sl_load_options o;
        memset(&o, 0, sizeof o);
        o.no_mmap = no_mmap;
        sl_status st = sl_scene_load(g_path, &o, NULL, &s, &err);
        if (st == SL_OK) {
            sl_scene_stats stats;
            sl_scene_get_stats(s, &stats);
            for (uint32_t i = 0; i < stats.object_count; i++)
                (void)sl_scene_object(s, i);
            (void)sl_scene_bsp_find_leaf(s, (sl_vec3){0, 0, 0});
            (void)sl_scene_ground_height(s, 1.5f, -2.5f);
            sl_scene_destroy(s);
        }
        if ((st == SL_OK) != (mem == SL_OK)) {
            fprintf(stderr, "slscene: the file (%s) says %d, memory says %d: %s\n", no_mmap ? "read" : "mapped", st,
                    mem, err.message);
            abort();
        }
    }
}

static void pvs_case(const uint8_t *data, size_t size)
{
    sl_pvs p = NULL;
    sl_error err;
    sl_status mem = sl_pvs_load_memory(data, size, "fuzz", NULL, &p, &err);
    if (p)
        sl_pvs_destroy(p);
    if (!write_file(data, size))
        return;
    sl_status st = sl_pvs_load(g_path, NULL, &p, &err);
    if (st == SL_OK) {
        sl_pvs_info in;
        sl_pvs_get_info(p, &in);
        uint32_t cap = 0, n;
        for (uint32_t c = 0; c < in.cell_count; c++)
            cap = cap > sl_pvs_cell_count(p, c) ? cap : sl_pvs_cell_count(p, c);
        uint32_t *ids = malloc(((size_t)cap + 1) * sizeof *ids);
        for (uint32_t c = 0; ids && c < in.cell_count && c < 4096; c++)
            (void)sl_pvs_cell_set(p, c, ids, cap, &n, &err);
        (void)sl_pvs_verify(p, &err);
        free(ids);
        sl_pvs_destroy(p);
    }
    if ((st == SL_OK) != (mem == SL_OK)) {
        fprintf(stderr, "slpvs: the file says %d, memory says %d: %s\n", st, mem, err.message);
        abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    bool pvs = data[0] & 1;
    data++, size--;
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            if (pvs)
                fx_fix_slpvs(copy, size);
            else
                fx_fix_slscene(copy, size);
        }
        if (pvs)
            pvs_case(copy, size);
        else
            scene_case(copy, size);
    }
    free(copy);
    if (g_path[0])
        unlink(g_path);
    return 0;
}

/* libFuzzer target: .pk3 (zip) archives held in memory: list the maps, then import the first few
 * by name and the archive's only map by default. Entries are capped at 4 MiB and the triangle
 * budget is small, so hostile sizes fail fast instead of exhausting memory.
 *
 * With SL_FUZZ_CLI_LIMITS=1 in the environment the limits are the command line's instead
 * (SL_PK3_MAX_ENTRY_BYTES, 512 MiB, and SL_Q3_MAX_TRIANGLES, 64 Mi triangles), so that the
 * large-allocation paths are fuzzed too; scripts/fuzz.sh runs it so once per run, with
 * -malloc_limit_mb and -rss_limit_mb raised to match. */
#include "import/pk3.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

typedef struct names {
    char entry[4][256];
    int count;
} names;

static void collect(void *user, const char *entry)
{
    names *n = user;
    if (n->count < 4)
        snprintf(n->entry[n->count++], sizeof n->entry[0], "%s", entry);
}

static bool cli_limits(void)
{
    static int on = -1;
    if (on < 0) {
        const char *e = getenv("SL_FUZZ_CLI_LIMITS");
        on = e && e[0] == '1';
    }
    return on;
}

static void import(const uint8_t *data, size_t size, const char *map)
{
    sl_scene scene;
    sl_error err;
    size_t max_entry = cli_limits() ? SL_PK3_MAX_ENTRY_BYTES : (size_t)4 << 20;
    uint64_t max_tris = cli_limits() ? SL_Q3_MAX_TRIANGLES : (uint64_t)1 << 20;
    if (sl_pk3_import_memory(data, size, "fuzz.pk3", map, max_entry, max_tris, NULL, NULL, &scene, &err) == SL_OK)
        sl_scene_destroy(scene);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    names n;
    memset(&n, 0, sizeof n);
    sl_error err;
    if (sl_pk3_list_maps_memory(data, size, "fuzz.pk3", collect, &n, &err) != SL_OK)
        return 0;
    for (int i = 0; i < n.count; i++)
        import(data, size, n.entry[i]);
    import(data, size, NULL);
    return 0;
}

/* libFuzzer target: .pk3 (zip) archives held in memory: list the maps, then import the first few
 * by name and the archive's only map by default. Entries are capped at 4 MiB and the triangle
 * budget is small, so hostile sizes fail fast instead of exhausting memory. */
#include "scene/pk3.h"

#include <stdint.h>
#include <stdio.h>
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

static void import(const uint8_t *data, size_t size, const char *map)
{
    sl_scene scene;
    sl_error err;
    if (sl_pk3_import_memory(data, size, "fuzz.pk3", map, (size_t)4 << 20, (uint64_t)1 << 20, NULL, NULL, &scene,
                             &err) == SL_OK)
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

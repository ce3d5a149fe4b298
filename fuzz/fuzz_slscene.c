/* libFuzzer target for the .slscene reader (sl_scene_load_memory).
 *
 * Each input is loaded twice: as it is (the checksums reject nearly every mutation, which tests
 * the header and table checks), and again with every checksum recomputed first, so that the
 * mutations reach the section parsers and the structural validation behind the checksums.
 * A loaded scene is read through a few accessors so that a bad pointer would be touched. */
#include "core/sl_core.h"
#include "sightline/slscene.h"

#include <stdlib.h>
#include <string.h>

/* The documented layout (docs/slscene-format.md). */
enum { HDR = 64, H_COUNT = 24, H_ENTRY_SIZE = 28, H_TABLE = 32, H_TABLE_HASH = 48, H_HASH = 56 };
enum { E_OFFSET = 16, E_SIZE = 24, E_HASH = 32 };

static uint32_t get32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t get64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static void put64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

/* Recompute the section, table and header checksums wherever they lie inside the buffer. */
static void fix_checksums(uint8_t *f, size_t size)
{
    if (size < HDR)
        return;
    uint64_t n = get32(f + H_COUNT), es = get32(f + H_ENTRY_SIZE), t = get64(f + H_TABLE);
    if (es >= 48 && es <= 4096 && n <= 4096 && t <= size && n * es <= size - t) {
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

static void touch(sl_scene s)
{
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    for (uint32_t i = 0; i < st.object_count; i++)
        (void)sl_scene_object(s, i);
    /* format 1.1: materials (their texture strings are read), object materials, UVs */
    for (uint32_t i = 0; i <= st.material_count; i++) {
        sl_material m;
        if (sl_scene_material(s, i, &m) && m.base_color_texture && !sl_texture_path_check(m.base_color_texture, NULL))
            abort(); /* the reader let an invalid texture path through */
    }
    for (uint32_t i = 0; i < st.mesh_count; i++) {
        sl_mesh_view mv = sl_scene_mesh(s, i);
        if (mv.uvs && mv.vertex_count)
            (void)(mv.uvs[0] + mv.uvs[2 * (size_t)mv.vertex_count - 1]);
    }
    for (uint32_t i = 0; i < st.footprint_count; i++)
        (void)sl_scene_footprint(s, i);
    /* format 1.2: the shrunk occluder levels (their footprints' vertices are read) */
    for (uint32_t l = 0; l < sl_scene_occluder_level_count(s); l++) {
        sl_occluder_level_view lv = sl_scene_occluder_level(s, l);
        for (uint32_t k = 0; k < lv.footprint_count; k++) {
            sl_footprint_view f = sl_scene_occluder_level_footprint(s, l, k);
            if (!f.xy || f.vertex_count < 3)
                abort(); /* the reader let a bad level footprint through */
            (void)(f.xy[0] + f.xy[2 * (size_t)f.vertex_count - 1]);
        }
    }
    (void)sl_scene_bsp_find_leaf(s, (sl_vec3){0, 0, 0});
    (void)sl_scene_ground_height(s, 1.5f, -2.5f);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sl_scene s = NULL;
    sl_error err;
    if (sl_scene_load_memory(data, size, "fuzz", NULL, &s, &err) == SL_OK) {
        touch(s);
        sl_scene_destroy(s);
    }
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    fix_checksums(copy, size);
    if (sl_scene_load_memory(copy, size, "fuzz", NULL, &s, &err) == SL_OK) {
        touch(s);
        sl_scene_destroy(s);
    }
    free(copy);
    return 0;
}

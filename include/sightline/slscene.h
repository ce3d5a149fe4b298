/* The native scene file, .slscene: a versioned little-endian binary with a header, a section
 * table and an XXH3 checksum per section and for the table. Bulk sections are 64-byte aligned so
 * that a loaded scene maps them straight from the file (mmap) without copying. The byte layout is
 * documented in docs/slscene-format.md. Same scene in, byte-identical file out. */
#ifndef SIGHTLINE_SLSCENE_H
#define SIGHTLINE_SLSCENE_H

#include "core.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_load_options {
    bool no_mmap;               /* read into owned memory instead of mapping the file */
    bool skip_checksums;        /* trust section checksums (structure is still validated) */
    sl_progress progress;
} sl_load_options;

/* Write a scene to path (atomically: temporary file, then rename). */
SL_API sl_status sl_scene_save(sl_scene scene, const char *path, sl_error *err);

/* Load a .slscene. opt may be NULL (mmap, checksums verified). Every section is validated before
 * use; a bad file fails with SL_ERROR_FORMAT naming the file, the offset or element and why. */
SL_API sl_status sl_scene_load(const char *path, const sl_load_options *opt, const sl_allocator *alloc, sl_scene *out,
                               sl_error *err);

/* Load from bytes in memory (copied). `name` is used in messages. */
SL_API sl_status sl_scene_load_memory(const void *data, size_t size, const char *name, const sl_allocator *alloc,
                                      sl_scene *out, sl_error *err);

/* Load any supported scene by extension: .slscene, .bsp, .pk3 (with map "name"), or any assimp
 * format. `map` may be NULL. */
SL_API sl_status sl_scene_open(const char *path, const char *map, const sl_allocator *alloc, sl_scene *out, sl_error *err);
/* sl_scene_open with import options for the importers (assimp: allowed external references, file
 * size limit; Quake III: scale, bezier level); opt may be NULL, and is unused for .slscene. */
struct sl_import_options;
SL_API sl_status sl_scene_open_with(const char *path, const char *map, const struct sl_import_options *opt,
                                    const sl_allocator *alloc, sl_scene *out, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

/* The native scene file, .slscene: a versioned little-endian binary with a header, a section
 * table and an XXH3 checksum per section and for the table. Bulk sections are 64-byte aligned so
 * that a loaded scene can map them straight from the file (mmap) without copying, on request. The byte layout is
 * documented in docs/slscene-format.md. Same scene in, byte-identical file out. */
#ifndef SIGHTLINE_SLSCENE_H
#define SIGHTLINE_SLSCENE_H

#include "core.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_load_options {
    bool no_mmap;               /* obsolete: reading into owned memory is the default; true wins over map */
    bool skip_checksums;        /* trust section checksums (structure is still validated) */
    sl_progress progress;
    /* Map the file (mmap) and let the scene's arrays point into it instead of reading it into
     * memory from the allocator: faster (no copy), but the scene then reads the file's pages for
     * as long as it lives, and if another process truncates or rewrites the file in place (cp over
     * it, a tool writing without rename) meanwhile, the next access to a lost page kills this
     * process with SIGBUS (the library installs no signal handler) or reads the other file's
     * bytes. Only map files nothing writes while they are loaded; replacing a file by rename
     * (what sl_scene_save and every Sightline tool do) is safe either way. */
    bool map;
} sl_load_options;

/* Write a scene to path (atomically: temporary file, then rename). */
SL_API sl_status sl_scene_save(sl_scene scene, const char *path, sl_error *err);

/* Load a .slscene. opt may be NULL (read into memory, checksums verified): the scene never
 * touches the file again, whatever later happens to it. Every section is validated before
 * use; a bad file fails with SL_ERROR_FORMAT naming the file, the offset or element and why. */
SL_API sl_status sl_scene_load(const char *path, const sl_load_options *opt, const sl_allocator *alloc, sl_scene *out,
                               sl_error *err);

/* Load from bytes in memory (copied). `name` is used in messages. */
SL_API sl_status sl_scene_load_memory(const void *data, size_t size, const char *name, const sl_allocator *alloc,
                                      sl_scene *out, sl_error *err);

/* Load any supported scene by extension: .slscene, .bsp, .pk3 (with map "name"), or any assimp
 * format. `map` may be NULL. This and sl_scene_open_with run the importers: full library
 * (libsightline) only; with libsightline_runtime use sl_scene_load. */
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

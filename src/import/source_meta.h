/* The "source" metadata of an imported scene, written so that the same input gives the same
 * bytes however its path was spelled (docs/slscene-format.md, "Metadata"): the file's base name
 * (for a map inside a .pk3, "ARCHIVE.pk3:maps/NAME.bsp" with the archive's base name) and the
 * XXH3-64 of the bytes read, as 16 lower-case hex digits (what `xxhsum -H3` prints). */
#ifndef SL_SCENE_SOURCE_META_H
#define SL_SCENE_SOURCE_META_H

#include "scene/scene_internal.h"

/* The last component of path (after the last '/' or '\\'); path itself when it has none. */
const char *sl_path_base_name(const char *path);

/* Set "source" to the base name of name and "source.xxh3" to the hash of data[0..size). */
sl_status sl_scene_set_source(sl_scene scene, const char *name, const void *data, size_t size, sl_error *err);

/* The same for a file on disk: its bytes are hashed in chunks (no whole-file buffer). */
sl_status sl_scene_set_source_file(sl_scene scene, const char *path, sl_error *err);

/* Set "source" to "BASE(archive):entry" (a map read from an archive; "source.xxh3" stays the hash
 * of the entry's bytes, set by sl_scene_set_source). */
sl_status sl_scene_set_source_entry(sl_scene scene, const char *archive, const char *entry, sl_error *err);

#endif

/* Internal: Quake III .pk3 (zip) archive access through libzip, shared by the Quake III importer,
 * its tests and the fuzz targets. The public entry points are sl_import_q3bsp and
 * sl_pk3_list_maps in sightline/import.h. */
#ifndef SL_SCENE_PK3_H
#define SL_SCENE_PK3_H

#include "sightline/import.h"

/* Largest uncompressed .bsp entry read from an archive (checked before allocating). */
#define SL_PK3_MAX_ENTRY_BYTES ((size_t)512 << 20)

/* Most triangles a map may produce (after patch tessellation) before the import fails with
 * SL_ERROR_LIMIT; real maps produce about 10^5. Checked before the geometry is allocated. */
#define SL_Q3_MAX_TRIANGLES ((uint64_t)64 << 20)

/* sl_import_q3bsp_memory with a tighter triangle budget (the fuzz targets use a small one). */
sl_status sl_q3bsp_import_memory_limited(const void *data, size_t size, const char *name,
                                         const sl_import_options *opt, uint64_t max_triangles,
                                         const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* True when the first bytes look like a zip archive ("PK\3\4", or "PK\5\6" for an empty one). */
bool sl_pk3_is_zip(const void *head, size_t size);

/* Turn a map name into its archive entry: "oa_dm1", "oa_dm1.bsp", "maps/oa_dm1" and
 * "maps/oa_dm1.bsp" all give "maps/oa_dm1.bsp"; any other path keeps its folders and gets ".bsp"
 * when it has no extension ("maps/_init/_init" gives "maps/_init/_init.bsp", so every name
 * sl_pk3_list_maps prints loads with or without it). Returns false when the name is empty, ends
 * in '/', has another extension ("textures/x.jpg") or does not fit in `cap` bytes. */
bool sl_pk3_entry_name(const char *map, char *out, size_t cap);

/* Import a map from a .pk3 archive held in memory. `map` as in sl_import_q3bsp; NULL or "" picks
 * the only .bsp of an archive that holds exactly one. `archive_name` names it in messages; an
 * entry whose uncompressed size exceeds max_entry_bytes fails with SL_ERROR_LIMIT before any
 * allocation; max_triangles as in sl_q3bsp_import_memory_limited. */
sl_status sl_pk3_import_memory(const void *data, size_t size, const char *archive_name, const char *map,
                               size_t max_entry_bytes, uint64_t max_triangles, const sl_import_options *opt,
                               const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* List the .bsp entries of a .pk3 archive held in memory (see sl_pk3_list_maps). */
sl_status sl_pk3_list_maps_memory(const void *data, size_t size, const char *archive_name,
                                  void (*fn)(void *user, const char *entry), void *user, sl_error *err);

#endif

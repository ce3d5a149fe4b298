/* Sightline importers and exporters.
 *
 * Any format assimp reads (OBJ, glTF 2.0/GLB, PLY, FBX, COLLADA, 3DS, ...) becomes a scene whose
 * objects are the file's nodes (one object per node with meshes; instanced meshes stay shared).
 * Quake III maps (IBSP version 46) are read from a .bsp file or from inside a .pk3 (zip) archive.
 *
 * Conventions: every importer produces metres, Z up. assimp files are taken as Y-up (glTF's rule,
 * and what most tools write) and rotated to Z-up unless up_axis says otherwise; unit_scale
 * multiplies coordinates. Quake III units are converted at 1/32 m per unit (a standing player,
 * 56 units tall, is 1.75 m), and Quake III is already Z-up.
 */
#ifndef SIGHTLINE_IMPORT_H
#define SIGHTLINE_IMPORT_H

#include "core.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sl_up_axis { SL_UP_Y = 0, SL_UP_Z = 1 } sl_up_axis;

typedef struct sl_import_options {
    float unit_scale;           /* metres per file unit; 0 means 1 (assimp) or 1/32 (Quake III) */
    sl_up_axis up_axis;         /* assimp files only; default SL_UP_Y */
    uint32_t split_triangles;   /* 0: one object per node; else split meshes larger than this into
                                   spatially compact objects of about this many triangles */
    uint32_t bezier_level;      /* Quake III patch tessellation level per bezier (0 means 8) */
    sl_progress progress;
} sl_import_options;

/* Default options (all zero). */
SL_API sl_import_options sl_import_defaults(void);

/* Import any file assimp reads into a new scene. */
SL_API sl_status sl_import_assimp(const char *path, const sl_import_options *opt, const sl_allocator *alloc,
                                  sl_scene *out, sl_error *err);

/* Import a Quake III map. `path` is a .bsp file, or a .pk3 archive with `map` naming the entry
 * ("maps/oa_dm1.bsp" or just "oa_dm1"); map is ignored for a .bsp file. */
SL_API sl_status sl_import_q3bsp(const char *path, const char *map, const sl_import_options *opt,
                                 const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* Import a Quake III map already in memory (the bytes of a .bsp). `name` is used in messages. */
SL_API sl_status sl_import_q3bsp_memory(const void *data, size_t size, const char *name, const sl_import_options *opt,
                                        const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* List the .bsp entries of a .pk3 archive: calls fn for each entry name ("maps/x.bsp"). */
SL_API sl_status sl_pk3_list_maps(const char *pk3_path, void (*fn)(void *user, const char *entry), void *user,
                                  sl_error *err);

/* Export a scene through assimp. `format` is an assimp export id ("obj", "gltf2", "glb2", "ply",
 * "collada", "stl", ...) or NULL to choose from the file extension. Written atomically. Output is
 * Y-up for glTF (its rule) and Z-up otherwise unless the options say SL_UP_Y. */
SL_API sl_status sl_export_assimp(sl_scene scene, const char *path, const char *format, sl_up_axis up_axis,
                                  sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

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
    /* assimp files: what the references inside a model (glTF buffers and images, OBJ material
     * libraries, any file assimp opens besides the model) may resolve to. By default only files
     * inside the model's own folder (after symlinks and '..'); each entry here allows one more
     * folder (everything below it) or, when it names a file, that file. A reference resolving
     * anywhere else fails the import, naming the reference and the folder. The list and its
     * strings are borrowed for the call only: the importer copies what it needs (canonical
     * paths) through its allocator and frees them before returning. */
    const char *const *allow_external;
    uint32_t allow_external_count;
    /* assimp files: the largest file assimp may open (the model or a reference); 0 means 4 GiB.
     * Only regular files are opened (never a FIFO or a device), read-only. */
    uint64_t max_file_bytes;
    /* assimp files: where assimp runs. By default (false) in a child process (fork()): assimp 5.2
     * reads out of bounds, crashes and loops on some malformed files (PLY and STL among them,
     * found by fuzzing), which in this process could corrupt its memory or kill it. The child
     * imports, writes the scene as .slscene into an anonymous memory file and exits; this process
     * reads that back with the validating .slscene reader. A child that crashes, is killed or
     * exits without a result fails the import with SL_ERROR_FORMAT naming the signal or status;
     * progress and cancellation reach `progress` as in this process. The child's allocations
     * go through `alloc` in the child's copy of this process. true: assimp runs in this process
     * (debugging; or where fork() is not allowed). */
    bool in_process;
    /* isolated assimp import only: kill the child after this many milliseconds and fail with
     * SL_ERROR_LIMIT (0: no limit) */
    uint32_t timeout_ms;
} sl_import_options;

/* Default options (all zero). */
SL_API sl_import_options sl_import_defaults(void);

/* Import any file assimp reads into a new scene. Every file assimp opens goes through a
 * read-only IO system confined as opt->allow_external says; assimp's messages are passed on with
 * control bytes and non-UTF-8 bytes escaped and cut short, never with raw file content. assimp
 * runs in a child process unless opt->in_process (see there). Thread safety: may be called from
 * several threads at once with distinct outputs; the isolated import forks, so a caller whose
 * other threads hold locks the child needs (other than malloc's, which glibc resets) should
 * import in process. */
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

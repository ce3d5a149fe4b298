/* Sightline precomputed visibility: the .slpvs file that stores a potentially visible set (PVS)
 * per view cell, and reading it back (baking one: bake.h).
 *
 * A PVS assigns to every view cell (region.h) the ascending list of object ids that may be seen
 * from somewhere in the cell. Baking methods are named like cullers:
 *  - "sample": occluder shrinking with point sampling (Wonka's thesis, chapters 5 and 7):
 *    conservative for 2.5D scenes (building footprints as occluders);
 *  - "adjustable": the adjustable (angular) shrinking of Koldas's thesis (chapter 4):
 *    conservative, visible sets valid in an eps-disk around a point, cells covered by disks;
 *  - "extproj": extended projections (Durand et al., SIGGRAPH 2000): occluders and objects
 *    projected from the whole cell onto planes and fused in an extended depth map; conservative
 *    for 2.5D scenes (building footprints as occluders);
 *  - "mappvs": a Quake III map's own cluster PVS stored as a Sightline PVS (aggressive: it is
 *    whatever the map's compiler produced), for verification and comparison;
 *  - a method is one file in src/region and one line in the method registry (guided visibility
 *    sampling, "gvs", plugs in the same way).
 * sl_pvs_method_count/info list them with their options (docs/pvs.md). Baking is declared in
 * bake.h and needs the full library (libsightline); this header is the run time
 * (libsightline_runtime): the file, its reader and the scene key.
 *
 * The bake distributes cells over OpenMP threads (sl_pvs_build; the `sightline pvs build` command
 * also spans MPI processes under mpiexec, without the library needing MPI); each cell's set is a function of the scene, the cells and the options only,
 * and the file is written in cell order, so the output is byte-identical whatever the thread or
 * process count. A checkpoint journal makes an interrupted bake resumable without recomputing or
 * losing finished cells.
 *
 * File (docs/pvs.md has the byte layout): a versioned header and section table with an XXH3-64
 * checksum per section; the view-cell table; per cell the set delta-coded (varint gaps) in blocks
 * of cells compressed with zstd, each block with its own checksum; build metadata. Loading reads
 * the file (or maps it, on request) and checks everything but the compressed blocks, which are
 * checked when first decoded (sl_pvs_verify checks them all). Written to a temporary file and
 * renamed.
 */
#ifndef SIGHTLINE_PVS_H
#define SIGHTLINE_PVS_H

#include "core.h"
#include "geom.h"
#include "scene.h"
#include "region.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_pvs_t *sl_pvs;

/* ---- the file ---------------------------------------------------------------------------------- */

typedef struct sl_pvs_info {
    uint32_t version_major, version_minor;
    uint32_t cell_count, object_count;
    uint32_t block_cells, block_count;
    uint64_t scene_key;         /* sl_pvs_scene_key of the scene it was baked for */
    uint64_t cells_key;         /* sl_viewcells_key of its cells */
    uint64_t visible_total;     /* sum over cells of the set sizes */
    uint32_t min_visible, max_visible;
    double mean_visible;
    double mean_culled;         /* mean over cells of 1 - |set| / object_count */
    uint64_t file_size;
    uint64_t data_bytes;        /* compressed sets */
    uint64_t raw_bytes;         /* the same, delta-coded before compression */
    uint32_t scene_key_version; /* format of scene_key (SL_PVS_SCENE_KEY_VERSION when current;
                                   1 in files of format 1.0) */
    uint32_t region_count;      /* nodes of the motion-region hierarchy (0: none; below) */
    double mean_regions_visible;/* mean over cells of the nodes marked visible */
} sl_pvs_info;

/* Format of sl_pvs_scene_key. 2: everything the methods read (below); 1 (files of format 1.0):
 * boxes, kinds and counts only, so a scene whose triangles moved inside the same boxes, or whose
 * BSP differed, had the same key. A file or a bake journal with another format is refused. */
#define SL_PVS_SCENE_KEY_VERSION 2u

/* Fingerprint of what a PVS depends on in a scene (XXH3-64 over the scene's arrays): the meshes
 * (records, vertex positions, indices), per object its mesh, kind and flags and, for static
 * objects, its transform and box; the footprints, the occluders and their transforms, the terrain,
 * the streets, and the BSP (planes, nodes, leaves, leaf objects, cluster PVS). Not normals,
 * colours, metadata or the placement of dynamic objects. Equal scenes give equal keys whatever
 * built them. */
SL_API uint64_t sl_pvs_scene_key(sl_scene scene);

/* Write a PVS: cell i's set is ids[offsets[i] .. offsets[i+1]), strictly ascending, each below
 * object_count. meta: "key=value" lines separated by '\n' (no NUL, no '=' in keys), may be NULL.
 * Atomic: written to a temporary file that is renamed over path. Deterministic bytes. */
SL_API sl_status sl_pvs_write(const char *path, sl_viewcells cells, uint32_t object_count, uint64_t scene_key,
                              const uint64_t *offsets, const uint32_t *ids, const char *meta, sl_error *err);

/* ---- motion regions (format 1.2) ----------------------------------------------------------------
 * Where dynamic objects (cars) can be: a box hierarchy over the regions of their motion records
 * (scene.h, sl_object_motion), baked with the sets (sl_pvs_build, bake.h), which marks per cell
 * the nodes that the static occluders may fail to hide from some point of the cell (Wonka's thesis
 * section 8.5). At run time a dynamic object is drawn when the deepest node holding its current
 * box is marked for the eye's cell (sl_pvs_region_box_visible); the object's own record is not
 * needed. Node 0 is the root; a node's children are consecutive, come after it and lie inside its
 * box; a node marked visible from a cell has every ancestor marked too. docs/motion.md. */
typedef struct sl_pvs_region {
    sl_aabb box;
    uint32_t first_child;       /* index of the first child (children are consecutive); 0 for a leaf */
    uint32_t child_count;       /* 0: a leaf */
    uint32_t parent;            /* SL_NONE for the root */
} sl_pvs_region;

/* What sl_pvs_write_regions stores: count nodes (at most SL_PVS_MAX_REGIONS) and one row per cell
 * of (count + 7) / 8 bytes, row c at visible + c * ((count + 7) / 8): node k is marked when bit
 * (k & 7) of byte (k >> 3) is set; bits past count are zero. */
typedef struct sl_pvs_regions {
    const sl_pvs_region *nodes;
    uint32_t count;
    const uint8_t *visible;
} sl_pvs_regions;
#define SL_PVS_MAX_REGIONS (1u << 20)
/* At most this many bytes of marks (cells x ((count + 7) / 8)): the reader's bound on one decoded block. */
#define SL_PVS_MAX_REGION_MARK_BYTES (1u << 28)

/* sl_pvs_write, with motion regions (regions NULL or count 0: none, a file of format 1.1, byte for
 * byte what sl_pvs_write writes). The hierarchy and rows are checked as the reader checks them. */
SL_API sl_status sl_pvs_write_regions(const char *path, sl_viewcells cells, uint32_t object_count, uint64_t scene_key,
                                      const uint64_t *offsets, const uint32_t *ids, const char *meta,
                                      const sl_pvs_regions *regions, sl_error *err);

/* sl_pvs_open flags. */
enum {
    /* Map the file (mmap) instead of reading it into memory. Saves the copy, but the handle then
     * reads the file's pages for as long as it lives: if another process truncates the file or
     * rewrites it in place (cp over it, a tool writing without rename) while it is open, the next
     * access to a lost page kills this process with SIGBUS, which the library does not catch.
     * Only map files nothing else writes while they are open. Replacing a file by rename (what
     * sl_pvs_write and every Sightline tool do) is safe either way. */
    SL_PVS_OPEN_MAP = 1u << 0,
};

/* Open a .slpvs. By default the whole file is read into memory from alloc (may be NULL), so
 * the handle never touches the file again and whatever happens to it later (truncated,
 * rewritten, deleted) leaves the handle's data as read; flags: SL_PVS_OPEN_MAP (see above).
 * Everything except the compressed blocks is validated; a bad file fails with SL_ERROR_FORMAT
 * naming the file, the offset or cell and why (a short file: "offset 40: truncated: expected N
 * bytes, file has M"); a newer major version with SL_ERROR_UNSUPPORTED. */
SL_API sl_status sl_pvs_open(const char *path, uint32_t flags, const sl_allocator *alloc, sl_pvs *out, sl_error *err);
/* sl_pvs_open(path, 0, alloc, out, err): read, not mapped. */
SL_API sl_status sl_pvs_load(const char *path, const sl_allocator *alloc, sl_pvs *out, sl_error *err);
/* The same from bytes in memory (copied). `name` stands for the file name in messages. */
SL_API sl_status sl_pvs_load_memory(const void *data, size_t size, const char *name, const sl_allocator *alloc,
                                    sl_pvs *out, sl_error *err);
/* Release it. NULL is ignored. */
SL_API void sl_pvs_destroy(sl_pvs pvs);
/* SL_OK when pvs was baked for scene: same object count and scene key, the key of the current
 * format. Else SL_ERROR_INVALID_ARGUMENT with a message that names the file and says to bake it
 * again (a file of an older key format: "FILE was baked with an older scene key (format 1); bake
 * it again: sightline pvs build ..."). */
SL_API sl_status sl_pvs_check_scene(sl_pvs pvs, sl_scene scene, sl_error *err);

/* Header figures (visible counts come from the set table: no decompression). */
SL_API void sl_pvs_get_info(sl_pvs pvs, sl_pvs_info *info);
/* The view cells (owned by the PVS). */
SL_API sl_viewcells sl_pvs_cells(sl_pvs pvs);
/* Build metadata value for key (method, options, timings ...), or NULL. */
SL_API const char *sl_pvs_meta(sl_pvs pvs, const char *key);
/* The whole metadata text ("key=value" lines). */
SL_API const char *sl_pvs_meta_text(sl_pvs pvs);
/* Number of objects in cell `cell`'s set (no decompression); 0 for a cell out of range. */
SL_API uint32_t sl_pvs_cell_count(sl_pvs pvs, uint32_t cell);
/* Decode cell `cell`'s set into out_ids (capacity >= its count), ascending. The block's checksum
 * is checked on first use. Uses a cache inside the handle: one thread at a time (from many
 * threads: sl_pvs_cursor below). Allocation-free after the first call. */
SL_API sl_status sl_pvs_cell_set(sl_pvs pvs, uint32_t cell, uint32_t *out_ids, uint32_t capacity, uint32_t *count,
                                 sl_error *err);
/* A cursor: its own decoder (a zstd context and one decompressed block) over a PVS, so that many
 * threads query one sl_pvs at once, each with its own cursor. Thread safety: any number of cursors
 * of one handle may be used at the same time from different threads (each cursor by one thread at
 * a time), alongside one thread calling sl_pvs_cell_set; the handle must outlive its cursors.
 * Create and destroy call the handle's allocator (which must then be thread-safe if cursors are
 * made from several threads). */
typedef struct sl_pvs_cursor_t *sl_pvs_cursor;
SL_API sl_status sl_pvs_cursor_create(sl_pvs pvs, sl_pvs_cursor *out, sl_error *err);
/* Release a cursor. NULL is ignored. */
SL_API void sl_pvs_cursor_destroy(sl_pvs_cursor cursor);
/* As sl_pvs_cell_set, through the cursor's decoder: the same ids and errors. Allocation-free after
 * the cursor's first call. */
SL_API sl_status sl_pvs_cursor_cell_set(sl_pvs_cursor cursor, uint32_t cell, uint32_t *out_ids, uint32_t capacity,
                                        uint32_t *count, sl_error *err);
/* The motion-region hierarchy (validated and held in memory at load: the calls below are
 * read-only and thread-safe): its node count (0 when the file has none), the nodes, and cell
 * `cell`'s row of marks ((count + 7) / 8 bytes as in sl_pvs_regions; NULL when the file has no
 * regions or the cell is out of range). */
SL_API uint32_t sl_pvs_region_count(sl_pvs pvs);
SL_API const sl_pvs_region *sl_pvs_region_nodes(sl_pvs pvs);
SL_API const uint8_t *sl_pvs_region_row(sl_pvs pvs, uint32_t cell);
/* May a dynamic object whose world box is `box` be seen, by the marks of `row` (a cell's row, or
 * the bitwise OR of several cells' rows)? Walks down from the root through the nodes that hold
 * the box: false as soon as one of them is unmarked (everything inside it is hidden from the
 * cells); true when the deepest holding node is marked, when no node holds the box, or when the
 * file has no regions or row is NULL. */
SL_API bool sl_pvs_region_box_visible(sl_pvs pvs, const uint8_t *row, const sl_aabb *box);
/* Check every checksum and decode every set (ranges, order, counts). */
SL_API sl_status sl_pvs_verify(sl_pvs pvs, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

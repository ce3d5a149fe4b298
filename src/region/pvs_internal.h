/* Internal pieces of the PVS layer shared by the file code, the bake drivers (threads, MPI) and
 * the baking methods: the method table (the set codec is in pvs/pvs_codec.h). */
#ifndef SL_PVS_INTERNAL_H
#define SL_PVS_INTERNAL_H

#include "sightline/bake.h"
#include "sightline/cull.h" /* sl_cull_guarantee */
#include "core/opts.h" /* sl_opts: the key=value option reader shared with the cullers */
#include "pvs/pvs_codec.h"
#include "pvs/viewcells_internal.h"

/* ---- baking methods ----
 * A method is src/region/method_<name>.c defining `const sl_pvs_method sl_pvs_method_<name>` plus
 * one line X(<name>) in SL_PVS_METHODS (pvs_methods.c). Life of a bake:
 *   configure(opts) -> prepare(scene, cells, config) -> shared state (read-only afterwards)
 *   per thread: worker_create(shared) -> { cell(worker, i) }* -> worker_destroy
 *   release(shared)
 * cell() must be a pure function of (scene, cells, config, i): the same set whatever thread,
 * process or order computes it — the bake's byte-identical output rests on this. */
typedef struct sl_pvs_cell_result {
    uint32_t *ids;              /* the method writes the set here, ascending (capacity: objects) */
    uint32_t count;
    uint64_t work;              /* method-specific effort counter (pixels, rays ...) for reports */
} sl_pvs_cell_result;

typedef struct sl_pvs_method {
    const char *name;
    const char *summary;
    const char *options_help;
    sl_cull_guarantee guarantee;
    size_t config_size;
    /* Read every option the method understands into config (zeroed, config_size bytes). */
    sl_status (*configure)(sl_opts *opts, void *config, sl_error *err);
    /* Scene-wide preparation (occluder shrinking, acceleration structures). *removed receives the
     * number of occluders that vanished (reported). alloc is never NULL. threads: the bake's thread
     * count, for a preparation that runs in parallel (0: OpenMP's default). */
    sl_status (*prepare)(sl_scene scene, sl_viewcells cells, const void *config, const sl_allocator *alloc,
                         uint32_t threads, void **shared, uint64_t *removed, sl_error *err);
    sl_status (*worker_create)(void *shared, void **worker, sl_error *err);
    sl_status (*cell)(void *worker, uint32_t cell, sl_pvs_cell_result *out, sl_error *err);
    void (*worker_destroy)(void *worker);
    void (*release)(void *shared);
    /* Optional: a sentence the user should read about these options (a bound not met ...), or
     * nothing (buf[0] = 0). */
    void (*notice)(const void *config, char *buf, size_t size);
} sl_pvs_method;

uint32_t sl_pvs_registry_count(void);
const sl_pvs_method *sl_pvs_registry_get(uint32_t index);
/* Find a method by name (NULL: the default "sample"); the message lists the methods. */
sl_status sl_pvs_registry_find(const char *name, const sl_pvs_method **out, sl_error *err);
/* Parse and configure a method's options; *config is allocated with a (config_size bytes, at least
 * 1) and must be freed with sl_free(a, *config, max(config_size, 1)). The effective options
 * ("key=value,...") are copied to effective (SL_OPTS_MAX_CHARS + 1 bytes) when not NULL. */
sl_status sl_pvs_method_configure(const sl_pvs_method *m, const char *options, const sl_allocator *a, void **config,
                                  char *effective, sl_error *err);

/* ---- the probe of pvs_update.c (method_adjustable.c) ----
 * adjustable's levels of disks for a cell (the same disks and options, coarse to fine, each level
 * testing the boxes the coarser one kept), with the pieces of the footprints f with
 * use_footprint[f] as the only occluders and `boxes` as the only objects: *visible is false when
 * every box is hidden from the whole cell by those occluders
 * (conservatively: then no point of the cell sees any of them). options: adjustable's options
 * (NULL: defaults). The probe is read-only once made; a worker per thread. */
sl_status sl_adj_probe_create(sl_scene scene, sl_viewcells cells, const char *options, const uint8_t *use_footprint,
                              const sl_aabb *boxes, uint32_t nbox, const sl_allocator *alloc, void **probe,
                              sl_error *err);
void sl_adj_probe_destroy(void *probe);
sl_status sl_adj_probe_worker_create(void *probe, void **worker, sl_error *err);
void sl_adj_probe_worker_destroy(void *worker);
sl_status sl_adj_probe_cell(void *worker, uint32_t cell, bool *visible, sl_error *err);
/* The same levels over the boxes subset[0..n) (distinct indices): visible[k] is set to 1 for each
 * box k of them that no level hides (the others are left as they are). */
sl_status sl_adj_probe_boxes(void *worker, uint32_t cell, const uint32_t *subset, uint32_t n, uint8_t *visible,
                             sl_error *err);

/* ---- the bake: what the thread and MPI drivers share (pvs_build.c) ----
 * begin configures and prepares the method; on the writing process it also takes the bake lock
 * and reads the checkpoint journal (resuming from it when asked). store records a finished cell
 * (encoded in memory, appended to the journal, which the first cell creates). finish writes the
 * .slpvs in cell order and removes the journal; end releases the lock. */
typedef struct sl_bake {
    const sl_allocator *a;
    sl_scene scene;
    sl_viewcells cells;
    const sl_pvs_method *method;
    void *config;
    char effective[SL_OPTS_MAX_CHARS + 1];
    void *shared;
    uint64_t removed;
    uint32_t cell_count, object_count;
    uint64_t key;               /* what the journal must match: scene, cells, method, options */
    uint64_t scene_key, cells_key, method_key; /* its parts, to say what differs */
    bool writer;
    /* results, per cell (writer only) */
    uint8_t **enc;
    uint32_t *enc_size, *counts;
    uint32_t *scratch;          /* object_count ids: decoding checks */
    uint8_t *done;
    uint32_t done_count, resumed, baked;
    double cell_seconds, max_cell_seconds;
    /* journal (writer only): created with the first finished cell (fd -1 until then) */
    int fd;
    char *journal;
    double last_sync;
    /* the bake lock (writer only): flock on "<journal>.lock", held from begin to end */
    int lock_fd;
    char *lock_path;
    char *output;               /* for messages */
    /* motion regions, marked by finish (writer only) */
    uint32_t regions;
    double region_seconds;
    /* set by an update before finish: the rows of the cells with region_keep[c] come from
     * region_old (when it holds the same hierarchy); region_copied receives how many did */
    sl_pvs region_old;
    const uint8_t *region_keep;
    uint32_t region_copied;
} sl_bake;

sl_status sl_bake_begin(sl_bake *b, sl_scene scene, sl_viewcells cells, const char *output,
                        const sl_pvs_build_options *opt, bool writer, sl_error *err);
sl_status sl_bake_store(sl_bake *b, uint32_t cell, const uint32_t *ids, uint32_t count, double seconds,
                        sl_error *err);
/* Store a cell already encoded (from the journal or another process): the bytes must decode to
 * exactly `count` ascending ids below the object count; journal: append it to the journal. */
sl_status sl_bake_store_encoded(sl_bake *b, uint32_t cell, const uint8_t *bytes, uint32_t size, uint32_t count,
                                double seconds, bool journal, sl_error *err);
sl_status sl_bake_finish(sl_bake *b, const char *output, const sl_pvs_build_options *opt, sl_error *err);
/* After a failure: add to the message that the finished cells are kept in the journal, if any. */
void sl_bake_note_kept(const sl_bake *b, sl_error *err);
void sl_bake_stats(const sl_bake *b, sl_pvs_build_stats *out);
void sl_bake_end(sl_bake *b);
/* The checkpoint journal's reader on bytes in memory, for a bake of cell_count cells over
 * object_count objects with bake key `key` (fuzz/fuzz_journal.c): *valid receives the length of
 * the valid prefix, *resumed the cells read back. */
sl_status sl_bake_journal_check(const uint8_t *data, size_t size, uint32_t cell_count, uint32_t object_count,
                                uint64_t key, const sl_allocator *alloc, size_t *valid, uint32_t *resumed,
                                sl_error *err);

/* Footprints above the ground (base_levels.c; docs/pvs.md): distinct bases, ascending. Per cell,
 * sl_cell_floor returns the lowest eye (zfloor) and sets *tb to the highest base <= zfloor
 * (-INFINITY if none): the occluders usable for the cell are those of base <= zfloor, and an
 * object wholly at or above tb is tested as it is. The methods take the bases of every footprint
 * of the scene (sl_base_levels_of_scene: a superset of their occluders' bases, which only raises
 * tb, and depends on the scene's bases alone: pvs update re-bakes a cell whose tb an edit
 * changes). */
typedef struct sl_base_levels {
    double *v;
    uint32_t n;
    size_t cap;
} sl_base_levels;
bool sl_base_levels_of_scene(sl_base_levels *b, sl_scene scene, const sl_allocator *a);
void sl_base_levels_free(sl_base_levels *b, const sl_allocator *a);
double sl_base_levels_top(const sl_base_levels *b); /* the highest base, -INFINITY if none */
double sl_cell_floor(const sl_base_levels *b, const sl_viewcell *vc, double *tb);

#endif

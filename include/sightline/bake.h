/* Sightline PVS baking (full library, libsightline; not in libsightline_runtime): the baking
 * methods, sl_pvs_build (cells over OpenMP threads, checkpoint journal) and, for a driver that
 * spreads the cells over processes itself (tools/pvs_mpi.c under MPI), a bake session (sl_bake_*)
 * that stores cell sets as they come and writes the same byte-identical .slpvs file.
 *
 * The file and its reader are in pvs.h; the view cells in region.h. Thread safety: the functions
 * here may be called from any thread; one sl_bake_session is used by one thread at a time.
 */
#ifndef SIGHTLINE_BAKE_H
#define SIGHTLINE_BAKE_H

#include "core.h"
#include "scene.h"
#include "cull.h"
#include "region.h"
#include "pvs.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- baking ------------------------------------------------------------------------------------ */

/* A registered baking method. Strings are static. */
typedef struct sl_pvs_method_desc {
    const char *name;
    const char *summary;
    const char *options_help;   /* one line per option: "key=TYPE (default D): meaning" */
    sl_cull_guarantee guarantee;
} sl_pvs_method_desc;

/* The registered bake methods: how many, and method `index` (SL_ERROR_INVALID_ARGUMENT beyond the
 * count). The registry is fixed at build time: thread-safe. */
SL_API uint32_t sl_pvs_method_count(void);
SL_API sl_status sl_pvs_method_info(uint32_t index, sl_pvs_method_desc *out, sl_error *err);
/* Check a method's options without a scene (unknown or malformed keys are rejected). */
SL_API sl_status sl_pvs_method_check_options(const char *method, const char *options, sl_error *err);

typedef struct sl_pvs_build_options {
    const char *method;         /* NULL: "sample" */
    const char *method_options; /* "key=value,..." for the method; NULL: defaults */
    uint32_t threads;           /* OpenMP threads; 0: all the machine offers */
    const char *checkpoint;     /* journal path; NULL: "<output>.ckpt" */
    bool resume;                /* continue from an existing journal (it must match the bake) */
    bool keep_checkpoint;       /* keep the journal after a successful bake */
    uint32_t stop_after;        /* testing: stop with SL_ERROR_CANCELLED after this many newly baked
                                   cells, leaving the journal behind; 0: never */
    sl_progress progress;       /* called under a lock, from whichever thread finished a cell */
    const sl_allocator *alloc;  /* called from several threads at once: must be thread-safe */
    bool fresh;                 /* remove a journal left by an earlier bake of this output and bake
                                   afresh; done under the bake lock, so the journal of a bake that
                                   runs is never touched (that bake is reported instead); not with
                                   resume */
    bool no_regions;            /* leave the motion regions out (default: when the scene has motion
                                   records, their box hierarchy is marked per cell and stored, file
                                   format 1.2; pvs.h, docs/motion.md) */
} sl_pvs_build_options;

typedef struct sl_pvs_build_stats {
    uint32_t cells;             /* cells in the PVS */
    uint32_t cells_baked;       /* computed by this run */
    uint32_t cells_resumed;     /* taken from the journal */
    uint32_t processes;         /* MPI processes (1 without MPI) */
    uint32_t threads;           /* threads per process */
    double seconds;             /* wall time of the whole bake */
    double cell_seconds;        /* sum over the cells baked here of their compute time */
    double max_cell_seconds;
    uint64_t visible_total;
    double mean_culled;         /* mean over cells of 1 - |set| / objects */
    uint64_t file_bytes;
    uint64_t occluders_removed; /* method-specific: occluders that vanished under shrinking */
    char method[32];            /* the method used */
    char options[256];          /* its effective options (truncated if longer) */
    char notice[256];           /* what the method wants the user to know about the options, or "" */
    uint32_t regions;           /* motion-region nodes stored (0: none) */
    double region_seconds;      /* wall time of marking them */
} sl_pvs_build_stats;

/* Bake the PVS of `cells` for `scene` with a method and write it to `output`. stats may be NULL. */
SL_API sl_status sl_pvs_build(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                              sl_pvs_build_stats *stats, sl_error *err);
/* Bake one cell into ids (capacity >= object count), for tests and tools; method and options as
 * for sl_pvs_build. Slow when repeated: prefer sl_pvs_build. */
SL_API sl_status sl_pvs_bake_cell(sl_scene scene, sl_viewcells cells, uint32_t cell, const char *method,
                                  const char *method_options, uint32_t *ids, uint32_t capacity, uint32_t *count,
                                  sl_error *err);

/* ---- a bake session: the bake for a driver of its own ------------------------------------------
 * What sl_pvs_build does, in pieces, for a driver that hands cells to processes itself
 * (tools/pvs_mpi.c): begin (configure and prepare the method, take the bake lock and read the
 * checkpoint journal when `writer`), bake cells with workers, store each cell's set as it comes
 * (journalled), finish (write the .slpvs file: byte-identical to sl_pvs_build's), end. A process
 * that only bakes (writer false) begins, bakes with workers and ends; it stores nothing.
 * Thread safety: a session is used by one thread at a time (the driver's lock), except that any
 * number of workers of one session run at once, each in one thread. */
typedef struct sl_bake_session_t *sl_bake_session;
typedef struct sl_bake_worker_t *sl_bake_worker;

/* Begin a bake of `cells` for `scene` into `output` with opt's method, options, checkpoint, resume,
 * fresh and alloc (threads, progress and stop_after are the driver's). On failure *out is NULL. */
SL_API sl_status sl_bake_session_begin(sl_scene scene, sl_viewcells cells, const char *output,
                                       const sl_pvs_build_options *opt, bool writer, sl_bake_session *out,
                                       sl_error *err);
/* Release the session, its journal file handle and the bake lock (the journal file stays unless
 * finish removed it). NULL is ignored. */
SL_API void sl_bake_session_end(sl_bake_session session);
/* What the journal must match (scene, cells, method, options): equal in every process of a bake. */
SL_API uint64_t sl_bake_session_key(sl_bake_session session);
SL_API uint32_t sl_bake_session_cell_count(sl_bake_session session);
SL_API uint32_t sl_bake_session_object_count(sl_bake_session session);
/* The allocator the bake uses (opt->alloc or the default; never NULL). */
SL_API const sl_allocator *sl_bake_session_allocator(sl_bake_session session);
/* Whether the cell's set is stored (taken from the journal or stored in this session). */
SL_API bool sl_bake_session_cell_done(sl_bake_session session, uint32_t cell);
SL_API uint32_t sl_bake_session_done_count(sl_bake_session session);
/* Cells stored by sl_bake_session_store/_store_encoded in this session (not resumed ones). */
SL_API uint32_t sl_bake_session_baked(sl_bake_session session);
/* The journal's path ("" before one is known) and the output's, for messages. */
SL_API const char *sl_bake_session_journal(sl_bake_session session);
SL_API const char *sl_bake_session_output(sl_bake_session session);

/* Store a cell's set (ascending ids, each below the object count) and journal it; seconds: its
 * compute time, for the statistics. Writer sessions only; a cell is stored once. */
SL_API sl_status sl_bake_session_store(sl_bake_session session, uint32_t cell, const uint32_t *ids, uint32_t count,
                                       double seconds, sl_error *err);
/* The same with the set encoded by sl_bake_encode_set (from another process): the bytes must
 * decode to exactly count ids. */
SL_API sl_status sl_bake_session_store_encoded(sl_bake_session session, uint32_t cell, const uint8_t *bytes,
                                               uint32_t size, uint32_t count, double seconds, sl_error *err);
/* Every cell stored: write output (opt as given to begin), remove the journal unless kept. */
SL_API sl_status sl_bake_session_finish(sl_bake_session session, const char *output, const sl_pvs_build_options *opt,
                                        sl_error *err);
/* After a failure: add to err's message that the finished cells are kept in the journal, if any. */
SL_API void sl_bake_session_note_kept(sl_bake_session session, sl_error *err);
/* The statistics so far (processes 1, threads 0: the driver sets those); all zero for NULL. */
SL_API void sl_bake_session_stats(sl_bake_session session, sl_pvs_build_stats *out);

/* A worker: the method's per-thread state, used by one thread at a time. */
SL_API sl_status sl_bake_worker_create(sl_bake_session session, sl_bake_worker *out, sl_error *err);
SL_API void sl_bake_worker_destroy(sl_bake_worker worker);
/* Bake one cell: its set into ids (capacity: the object count), ascending, and its size. */
SL_API sl_status sl_bake_worker_cell(sl_bake_worker worker, uint32_t cell, uint32_t *ids, uint32_t *count,
                                     sl_error *err);

/* ---- updating a bake after an edit (docs/pvs.md, "Updating a bake") ---------------------------
 * sl_pvs_update re-bakes only the cells an edit of the scene can affect and copies the other sets
 * (renumbered) from the old file: the output is byte-identical to sl_pvs_build of the edited scene
 * with the old file's method and options. The two scenes are matched by content (objects: mesh
 * positions and indices, kind, flags, transform, box; footprints: polygon, heights, object); objects
 * and footprints may be added, removed or moved. Refused with a message (nothing written): a file
 * not baked for old_scene (SL_ERROR_INVALID_ARGUMENT), a method other than adjustable and sample
 * (SL_ERROR_UNSUPPORTED), view cells that differ from the file's — `cells` are the edited scene's,
 * made as the full bake would make them; an edit of the streets, or footprints put over them,
 * changes them (SL_ERROR_INVALID_ARGUMENT) — and an edit of the terrain, the streets, the BSP or the
 * mesh occluders (SL_ERROR_UNSUPPORTED). The re-baked cells are journalled as sl_pvs_build does
 * (checkpoint: "<output>.ckpt" unless named; an existing one is refused). Thread safety: as
 * sl_pvs_build; old is read by this call only (sl_pvs_cell_set). */
typedef struct sl_pvs_update_options {
    uint32_t threads;           /* OpenMP threads; 0: all the machine offers */
    const char *checkpoint;     /* journal of the re-baked cells; NULL: "<output>.ckpt" */
    sl_progress progress;       /* "re-baking cells", done/total of the affected cells */
    const sl_allocator *alloc;  /* thread-safe */
    uint32_t weaken;            /* testing only, makes the update WRONG: 1 leaves out rule (a) (old
                                   sets holding a changed object), 2 the probe (rule b), 3 the
                                   touching footprints of a closed zone; 0: the update */
} sl_pvs_update_options;

typedef struct sl_pvs_update_stats {
    uint32_t cells;             /* cells in the file */
    uint32_t cells_affected;    /* re-baked */
    uint32_t cells_by_set;      /* of which rule (a): the old set holds a removed or zone object */
    uint32_t cells_by_probe;    /* rule (b): the probe could not hide the zone */
    uint32_t objects_old, objects_new;
    uint32_t objects_removed;   /* old objects without a match (removed or moved) */
    uint32_t objects_added;     /* new objects without a match (added or moved) */
    uint32_t footprints_changed;/* footprints without a match, old and new */
    uint32_t zone_footprints;   /* with the footprints touching them when zone_closed */
    bool zone_closed;           /* the method joins touching footprints (sample's merge, adjustable's
                                   fuse): the zone holds every footprint touching it, transitively */
    uint32_t zone_boxes;        /* boxes the probe tests */
    double seconds;             /* wall time of the whole update */
    double cpu_seconds;         /* CPU time of the process (all threads) during the update */
    double probe_seconds;       /* wall time of the probe */
    double prepare_seconds;     /* wall time of the method's preparation on the edited scene */
    double bake_seconds;        /* wall time of re-baking the affected cells */
    double cell_seconds;        /* sum over the re-baked cells of their compute time */
    double probe_cpu_seconds, prepare_cpu_seconds, bake_cpu_seconds; /* the three phases' process CPU time */
    char method[32];
    char options[256];
    uint32_t regions;           /* motion-region nodes in the output (0: none) */
    uint32_t region_rows_copied;/* cells whose region marks were copied from the old file (the cells
                                   kept, when both files hold the same hierarchy); the others are
                                   marked again */
    uint32_t cells_by_base;     /* rule (c): the edit changed the highest footprint base at or below
                                   the cell's lowest eye (docs/pvs.md, "Footprints above the
                                   ground"); appended */
} sl_pvs_update_stats;

/* Update the bake `old` of old_scene for new_scene (same view cells) into output: the cells the
 * edit can affect are re-baked, the others copied (the rules and errors above); stats (may be
 * NULL) says what was done. */
SL_API sl_status sl_pvs_update(sl_pvs old, sl_scene old_scene, sl_scene new_scene, sl_viewcells cells,
                               const char *output, const sl_pvs_update_options *opt, sl_pvs_update_stats *stats,
                               sl_error *err);

/* Encode an ascending id set as the .slpvs file does (varint gaps): at most 5 * count bytes into
 * out; returns the size. For sending sets between processes. */
SL_API size_t sl_bake_encode_set(const uint32_t *ids, uint32_t count, uint8_t *out);

#ifdef __cplusplus
}
#endif
#endif

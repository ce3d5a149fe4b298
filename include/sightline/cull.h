/* Sightline online culling: one interface for every method, and the registry that names them.
 *
 * A culler is created for a scene by method name with options given as "key=value" pairs
 * separated by commas or white space ("coherence=false, plane_masks=1"). Unknown keys, repeated
 * keys, empty or malformed values and values out of range are rejected with a message naming the
 * key and listing the valid ones. Each frame, sl_culler_cull_view turns a view (or sl_culler_cull a camera) into the ascending
 * list of object ids the method could not rule out; sl_culler_stats then tells what it cost.
 *
 * A method is conservative (it never drops an object that owns a pixel in the exact image: the
 * tests hold it to the oracle of truth.h with zero tolerance) or aggressive (it may drop some; its
 * missed pixels are measured). The guarantee may depend on the options. It holds inside the
 * domain of the oracles (docs/oracle.md, "One set of rules"): an eye in solid or void space of a
 * Quake III map (a BSP leaf without a cluster) is outside it, and there every culler returns its
 * frustum set (that of vfc) and sets sl_cull_stats.out_of_domain.
 *
 * Contract: the scene must outlive the culler and keep its objects (their number fixed); objects
 * may move (sl_scene_set_object_transform), after which sl_culler_scene_changed lets the method
 * refit. sl_culler_cull allocates nothing in steady state. One culler is used by one thread at a
 * time; distinct cullers on one scene may run in parallel while the scene does not change.
 * docs/culler-contract.md describes how to add a method (a file and one line in the registry).
 */
#ifndef SIGHTLINE_CULL_H
#define SIGHTLINE_CULL_H

#include "core.h"
#include "geom.h"
#include "scene.h"
#include "camera.h"
#include "view.h"
#include "raster.h"
#include "accel.h"
#include "backend.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_culler_t *sl_culler;

/* What a culler promises (docs/culler-contract.md, "Guarantees and resolution"). */
typedef enum sl_cull_guarantee {
    SL_CONSERVATIVE = 0, /* never drops an object visible in an image of the same view and projection
                            at ANY resolution and with any sample positions in the pixels (MSAA,
                            jitter, a client rendering at its own size): occluders count only where
                            they cover whole pixels of the culling resolution (inner coverage),
                            tested objects wherever they touch a pixel (outer coverage) */
    SL_AGGRESSIVE = 1,   /* may drop visible objects; reports missed pixels against the oracle */
    SL_CONSERVATIVE_AT_RESOLUTION = 2 /* never drops an object visible in the image at the camera's
                            own width x height sampled at pixel centres (the oracle's default); may
                            drop one seen only at another resolution or by other samples (the
                            `res=culling` option of the methods that have it) */
} sl_cull_guarantee;

/* "conservative", "aggressive" or "conservative-at-resolution". */
SL_API const char *sl_cull_guarantee_name(sl_cull_guarantee g);
/* Does guarantee g promise zero misses against an image of the same view and projection: any
 * image (at_culling_resolution false), or the image at the culling resolution sampled at pixel
 * centres (true)? SL_CONSERVATIVE: always; SL_CONSERVATIVE_AT_RESOLUTION: only when
 * at_culling_resolution; SL_AGGRESSIVE: never. */
SL_API bool sl_cull_guarantee_keeps_visible(sl_cull_guarantee g, bool at_culling_resolution);

/* Most named phases a method reports per frame. */
#define SL_CULL_MAX_PHASES 4

/* Per-frame statistics of the last sl_culler_cull. Counters a method has no use for stay 0. */
typedef struct sl_cull_stats {
    uint64_t objects_tested;    /* object boxes tested (frustum, occlusion, back-face ...) */
    uint64_t nodes_visited;     /* hierarchy nodes entered (BVH, grid cells, cull-map cells ...) */
    uint64_t objects_visible;   /* objects reported (filled by the interface) */
    uint64_t triangles_visible; /* their triangles: what a renderer would draw (filled by the interface) */
    uint64_t occlusion_tests;   /* boxes or nodes tested against occluders */
    uint64_t queries;           /* occlusion queries issued (hardware-style methods) */
    uint64_t pixels_rasterized; /* occluder pixels written into a depth/occlusion buffer */
    uint64_t pixel_queries;     /* buffer pixels read by occlusion tests */
    uint32_t phase_count;       /* named phases below, at most SL_CULL_MAX_PHASES */
    const char *phase_names[SL_CULL_MAX_PHASES]; /* static strings ("traverse", "rasterize" ...) */
    double phase_ms[SL_CULL_MAX_PHASES];
    double total_ms;            /* wall time of the whole sl_culler_cull call (filled by the interface) */
    bool out_of_domain;         /* the eye was outside the domain (a BSP leaf without a cluster, see
                                   sl_oracle_in_domain in truth.h): the result is the frustum set of
                                   vfc with its defaults, whatever the method (filled by the interface) */
    uint64_t query_stalls;      /* query results waited for before they were ready (a draw backend's
                                   latency; see backend.h). Appended (docs/versions.md: fields are
                                   added at the end) */
    double query_wait_ms;       /* time this frame spent waiting for query results: simulated ms
                                   of a CPU backend's clock (backend.h), else wall ms inside
                                   wait_query (the query cullers; appended, issue 15) */
} sl_cull_stats;

/* A registered method. Strings are static. */
typedef struct sl_cull_method_desc {
    const char *name;           /* what sl_culler_create takes: "vfc" */
    const char *summary;        /* one line: what it does, and the paper it follows */
    const char *options_help;   /* one line per option: "key=TYPE (default D): meaning" */
    sl_cull_guarantee guarantee;/* with the default options */
    bool res_culling;           /* the method takes res=culling: a tighter mode whose guarantee is
                                   SL_CONSERVATIVE_AT_RESOLUTION (its default, res=any, is
                                   resolution-independent) */
    const char *suits;          /* the scenes and views it suits, one short line ("cities with building
                                   footprints, eyes near the ground"); "" when the method says nothing.
                                   Appended (docs/versions.md) */
} sl_cull_method_desc;

/* Number of registered methods. */
SL_API uint32_t sl_cull_method_count(void);
/* Description of method `index` (0..count-1); SL_ERROR_NOT_FOUND beyond. */
SL_API sl_status sl_cull_method_info(uint32_t index, sl_cull_method_desc *out, sl_error *err);
/* Index of the method called `name`; SL_ERROR_NOT_FOUND (listing the methods) when there is none. */
SL_API sl_status sl_cull_method_find(const char *name, uint32_t *index, sl_error *err);
/* Check an options string for a method without a scene (what sl_culler_create would reject). */
SL_API sl_status sl_cull_method_check_options(const char *method, const char *options, sl_error *err);
/* Whether `method` with `options` can cull more than the view frustum on `scene`: false, with the
 * reason in why (at most why_size bytes, may be NULL), when the scene lacks what the method culls
 * with — the 2.5D methods (cullmap, horizon, dhorizon) need building footprints; the occlusion
 * methods (hzb, lazygrid, lazygrid-z, busygrid, hom, frusta) need footprints, SL_OBJECT_OCCLUDER
 * objects that are not see-through, occluder meshes (sl_synth_occluders makes them for imported
 * models) or all_objects=true. Such a culler still builds and returns the frustum's set; the bench,
 * the demo and `sightline methods --scene` report it as "not applicable" instead of running it as
 * vfc. Errors: the method's or options' (sl_cull_method_check_options). Thread-safe (reads the scene). */
SL_API sl_status sl_cull_method_applicable(const char *method, const char *options, sl_scene scene, bool *applicable,
                                           char *why, size_t why_size, sl_error *err);

/* Create a culler of method `method` for a scene. options may be NULL or "" (defaults); alloc may
 * be NULL. Fails with SL_ERROR_NOT_FOUND for an unknown method and SL_ERROR_INVALID_ARGUMENT for
 * bad options. */
SL_API sl_status sl_culler_create(const char *method, sl_scene scene, const char *options, const sl_allocator *alloc,
                                  sl_culler *out, sl_error *err);
/* What a culler may be created with besides its options (sl_culler_create_with). A zeroed struct
 * (or NULL) is what sl_culler_create uses. */
typedef struct sl_culler_params {
    /* A draw backend (backend.h) for the methods that draw (gl-stopwait, chc, chc++); copied at creation, its user
     * pointer must stay valid while the culler lives. NULL: such a method uses a CPU reference
     * backend of its own (sl_draw_backend_cpu). A method that draws nothing refuses a backend
     * (SL_ERROR_INVALID_ARGUMENT naming the method). */
    const sl_draw_backend *backend;
    /* A shared per-scene acceleration handle (accel.h) of the same scene, whose object BVH the
     * methods that walk one use instead of building their own (their leaf_size must match the
     * handle's, else SL_ERROR_INVALID_ARGUMENT naming both); methods without an object BVH ignore
     * it. Rules for moving objects: accel.h, "shared per-scene acceleration". */
    sl_scene_accel accel;
} sl_culler_params;

/* Does the method take a draw backend (sl_culler_params.backend)? An unknown method: false. */
SL_API bool sl_cull_method_draws(const char *method);

/* sl_culler_create with params (may be NULL). The culler keeps params->accel and a copy of
 * *params->backend; one culler is still used by one thread at a time, and cullers sharing one
 * accel may cull on distinct threads at once. */
SL_API sl_status sl_culler_create_with(const char *method, sl_scene scene, const char *options,
                                       const sl_culler_params *params, const sl_allocator *alloc, sl_culler *out,
                                       sl_error *err);
/* Release a culler. NULL is ignored. */
SL_API void sl_culler_destroy(sl_culler culler);

/* Cull one frame: write the ids of the objects that may be visible from view (view.h: from a
 * camera or an engine's matrices; off-axis, orthographic, reversed-z, infinite far), strictly
 * ascending, to out_ids and their number to *out_count. capacity must be at least the scene's
 * object count. A view with an infinite far plane is culled as its sl_view_bound_far by the
 * scene's bounds (same visible set). Refused: a view no constructor made, or one whose near plane
 * the method's depth format cannot resolve (sl_view_check_depth, naming the limit). */
SL_API sl_status sl_culler_cull_view(sl_culler culler, const sl_view *view, uint32_t *out_ids, uint32_t capacity,
                                     uint32_t *out_count, sl_error *err);
/* sl_culler_cull_view of sl_view_from_camera(cam): the same ids as before views existed. */
SL_API sl_status sl_culler_cull(sl_culler culler, const sl_camera *cam, uint32_t *out_ids, uint32_t capacity,
                                uint32_t *out_count, sl_error *err);
/* Statistics of the last cull (all zero before the first). */
SL_API void sl_culler_stats(sl_culler culler, sl_cull_stats *out);
/* Tell the culler that objects moved since the last frame, so that it refits what depends on
 * their boxes. */
SL_API sl_status sl_culler_scene_changed(sl_culler culler, sl_error *err);
/* The guarantee of this culler with its options. */
SL_API sl_cull_guarantee sl_culler_guarantee(sl_culler culler);
/* Name of the culler's method. */
SL_API const char *sl_culler_method(sl_culler culler);
/* The effective options, defaults included, as "key=value,key=value" (for reports). */
SL_API const char *sl_culler_options(sl_culler culler);

/* ---- Instant Visibility (the `instant` method, docs/instant.md) ----
 * What an `instant` culler has done since its creation: updates (visibility computations) and
 * their times and sizes, stalls (late=stall: frames that waited for a set valid at the displayed
 * eye) and frames at risk (late=continue: frames displayed with a set computed too far away). */
typedef struct sl_instant_stats {
    uint64_t frames;            /* cull calls */
    uint64_t updates;           /* visibility updates started (posted or computed in place) */
    uint64_t adopted;           /* updates that became the displayed set */
    uint64_t startups;          /* frames without any set (the first, after scene_changed) */
    uint64_t stalls;            /* late=stall: frames that waited */
    uint64_t frames_at_risk;    /* late=continue: frames whose eye was outside the set's eps-ball */
    uint64_t eps_short;         /* adaptive eps: updates for which no stored level was large enough */
    double stall_ms;            /* time stalled: simulated ms (clock=simulated) or wall ms */
    double sim_wait_ms;         /* clock=simulated: wall ms the caller waited for a thread behind the clock */
    double vis_ms_last, vis_ms_total; /* wall time of the updates adopted */
    uint64_t set_size_total;    /* objects in the adopted sets, summed */
    uint32_t set_size_last;
    uint32_t levels;            /* stored occluder levels of the scene (0: its own footprints, eps 0) */
    float eps_last;             /* eps of the last adopted set */
    float eps_displayed;        /* eps of the set displayed by the last frame */
    bool stalled_now, at_risk_now; /* the last frame stalled / was at risk */
    double clock_ms;            /* the frame clock of the last frame (simulated or wall ms) */
} sl_instant_stats;
/* SL_ERROR_INVALID_ARGUMENT when c is not an `instant` culler. Same thread rules as sl_culler_stats. */
SL_API sl_status sl_instant_get_stats(sl_culler c, sl_instant_stats *out, sl_error *err);

/* ---- occlusion recordings (debugging the occlusion framework) ----
 * A culler of the occlusion framework created with record=FILE writes frame debug_frame's
 * occluder batches and queries to FILE (docs/occlusion.md). A replay re-runs them on the
 * rasterizer alone, on any instruction set, and tells whether the answers are the recorded ones
 * (`sightline occlusion replay`). Distinct replays may run on distinct threads. */

/* What a replay found. */
typedef struct sl_occ_replay_report {
    uint32_t width, height;
    uint32_t batches, queries;
    uint64_t triangles;
    uint32_t mismatches;      /* queries whose answer differs from the recorded one */
    uint32_t first_mismatch;  /* index of the first, or UINT32_MAX */
    uint32_t occluded;        /* recorded OCCLUDED answers */
    uint64_t depth_hash;      /* XXH3 of the final depth buffer (read_depth) */
} sl_occ_replay_report;

/* Replay a recording on a fresh single-threaded context with the given instruction set (AUTO:
 * the best available): render every batch, re-run every query, compare the answers. Validates
 * the whole file first (SL_ERROR_FORMAT naming the offset and the field). */
SL_API sl_status sl_occ_replay(const char *path, sl_raster_isa isa, const sl_allocator *alloc, sl_occ_replay_report *out,
                               sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

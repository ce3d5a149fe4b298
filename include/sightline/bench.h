/* Sightline benchmark harness: every culling method judged against the exact point oracle, frame
 * by frame, on one scene.
 *
 * A bench holds a scene, the oracle (truth.h) and one culler per method (cull.h, created through
 * the registry by name, so every registered method is treated alike). Each frame renders the
 * oracle once and then runs every method on the same camera, timing each (the median of
 * `repeat` calls), and keeps one record per frame x method: what the method kept, what it would
 * draw, how it compares with the exact visible set (missed objects and pixels, over-estimation)
 * and the method's own counters. Summaries per method give the table of `sightline bench`;
 * writers produce the CSV/JSON rows, the Markdown summary, SVG plots and a top-down map PNG
 * (docs/bench.md has the formats).
 *
 * Methods that are not sl_cullers (a GPU method run by the viewer, a PVS lookup, a test's
 * hand-made answer) join as "external" methods: the caller computes their result for the current
 * frame and hands it to sl_bench_submit, which judges it exactly like a culler's.
 *
 * A bench must not outlive its scene; the scene must not change while a frame runs. One bench is
 * used by one thread at a time (the oracle starts its own helper threads).
 */
#ifndef SIGHTLINE_BENCH_H
#define SIGHTLINE_BENCH_H

#include <stdio.h>

#include "core.h"
#include "geom.h"
#include "scene.h"
#include "camera.h"
#include "view.h"
#include "cull.h"
#include "path.h"
#include "truth.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_bench_t *sl_bench;

/* Most methods in one bench, and most missed objects remembered per record. */
#define SL_BENCH_MAX_METHODS 64u
#define SL_BENCH_MISSED_KEEP 8u

typedef struct sl_bench_options {
    uint32_t width, height;   /* viewport of every camera and oracle resolution; 0 and 0: each
                                 camera's own (default 0, 0) */
    uint32_t threads;         /* oracle threads, 1..SL_ORACLE_MAX_THREADS (default 2) */
    uint32_t repeat;          /* cull calls per frame and method, 1..1000; the median time is kept
                                 (default 1) */
    const char *label;        /* name of the scene in reports ("city-small-1"); copied (default "scene") */
    sl_progress progress;     /* sl_bench_run_path reports frames done; returning false cancels */
    /* the bounds of the recommendation (sl_bench_recommend, the summaries): over-estimation at
     * most this (ratio of sums; 0: 2) and median cull time at most this many ms (0: 2). Appended */
    double max_overestimation, max_ms;
    /* Called after each frame is judged (frame: its index in the bench), e.g. to write each
     * method's set (sl_bench_last_result) or the oracle's (sl_bench_last_truth) while they are
     * there; returning false stops the run (SL_ERROR_CANCELLED). NULL: none. Appended */
    bool (*frame_done)(void *user, sl_bench bench, uint32_t frame);
    void *frame_user;
} sl_bench_options;

/* The defaults above. */
SL_API sl_bench_options sl_bench_default_options(void);

/* A method to run: its registry name and its options string (NULL or "": defaults). */
typedef struct sl_bench_method_spec {
    const char *name;
    const char *options;
} sl_bench_method_spec;

/* A registered method that cannot run with its default options, and why. */
typedef struct sl_bench_skip {
    const char *name;         /* the registry's (static) */
    char reason[512];         /* the method's own message, e.g. "pvs: option file=PATH is required ..." */
} sl_bench_skip;

/* Every registered method that accepts its default options, in registry order, into specs
 * (options NULL; at most capacity). A method that cannot run without an option (pvs needs a
 * baked file=PATH) is listed in skipped (at most skipped_capacity, may be NULL) with its reason;
 * *skipped_count (may be NULL) receives how many there are. Returns the number of specs written.
 * What `sightline bench` without --methods and `sightline demo` run. */
SL_API uint32_t sl_bench_registered_methods(sl_bench_method_spec *specs, uint32_t capacity, sl_bench_skip *skipped,
                                            uint32_t skipped_capacity, uint32_t *skipped_count);

/* A method of a bench, as reports show it. Strings belong to the bench. */
typedef struct sl_bench_method_info {
    const char *name;
    const char *options;      /* effective options, defaults included ("" for external methods) */
    sl_cull_guarantee guarantee; /* with these options */
    bool external;            /* results come from sl_bench_submit */
} sl_bench_method_info;

/* One frame: the camera and what the oracle found. */
typedef struct sl_bench_frame {
    uint32_t index;           /* 0.. in the order frames were run (what records are indexed by) */
    uint32_t source;          /* the pose's index in its path (sl_bench_run_path), else index;
                                 reports call this the frame number */
    float time;               /* the pose's time in seconds (sl_bench_run_path), else the index */
    sl_camera camera;         /* as rendered (viewport overridden by the options); for a frame of
                                 sl_bench_run_view of matrices, an approximate camera: the view's
                                 eye, orientation, near, far and vertical extent (no off-axis
                                 shift, no depth convention) */
    sl_view view;             /* the view the frame was culled from, exactly (after the options'
                                 viewport; an infinite far plane kept as given): reports print it
                                 for frames of matrices (docs/bench.md, "the view columns") */
    uint32_t visible_count;   /* exact visible set size */
    uint64_t triangles_visible; /* triangles of the visible objects (an exact method draws these) */
    uint64_t covered_pixels;  /* pixels showing some object */
    uint32_t objects_in_frustum; /* objects the oracle drew */
    uint64_t triangles_in_frustum;
    double oracle_ms;         /* wall time of the oracle render */
    bool out_of_domain;       /* the eye is outside the domain (sl_oracle_in_domain, docs/oracle.md):
                                 the frame is counted and skipped, no method runs and its records
                                 stay invalid */
} sl_bench_frame;

/* One method on one frame. */
typedef struct sl_bench_record {
    bool valid;               /* false: an external method not submitted for this frame */
    sl_cull_metrics metrics;  /* vs the oracle: |R|, |V|, missed, pixels, extra, triangles */
    sl_cull_stats stats;      /* the method's counters of the last call (zero for external) */
    double cull_ms;           /* median wall time over the repeats (sl_cull_stats.total_ms) */
    double cull_ms_min;       /* fastest of the repeats */
    uint32_t missed_kept;     /* min(missed_count, SL_BENCH_MISSED_KEEP) */
    uint32_t missed_ids[SL_BENCH_MISSED_KEEP];    /* the first missed objects, ascending ids */
    uint32_t missed_pixels[SL_BENCH_MISSED_KEEP]; /* their pixel counts */
} sl_bench_record;

/* Per-method summary over the bench's frames (the valid records only). */
typedef struct sl_bench_summary {
    uint32_t frames;          /* records counted */
    double objects_drawn_mean;     /* |R| */
    double triangles_drawn_mean;   /* triangles of R */
    double visible_mean;           /* |V| */
    double triangles_visible_mean; /* triangles of V */
    double overestimation_mean;    /* |R| / max(|V|, 1) */
    double extra_mean;             /* |R \ V| */
    uint64_t missed_objects_total; /* sum over frames of |V \ R| */
    uint64_t missed_pixels_total;
    uint32_t frames_with_misses;
    uint32_t first_miss_frame;     /* number (sl_bench_frame.source) of the first frame with a miss,
                                      SL_NONE without */
    uint32_t first_miss_object;    /* its first missed object, SL_NONE without */
    sl_series_summary cull_ms;     /* median, p95, max ... of the per-frame cull times */
    uint32_t frames_out_of_domain; /* frames of the bench skipped because the eye was outside the
                                      domain (not in `frames`) */
    double overestimation;         /* ratio of sums: objects drawn over objects the oracle sees,
                                      summed over the frames (the latter at least 1; 1 without
                                      frames): the reports' over-estimation. Appended */
    uint32_t frames_empty;         /* counted frames where the oracle sees no object. Appended */
} sl_bench_summary;

/* ---- lifetime ---- */

/* Create a bench for a scene with the given methods (each created through the registry; an
 * unknown method or bad options fail with the registry's message, prefixed by the method's
 * name). method_count may be 0 (external methods only). opt and alloc may be NULL. */
SL_API sl_status sl_bench_create(sl_scene scene, const sl_bench_method_spec *methods, uint32_t method_count,
                                 const sl_bench_options *opt, const sl_allocator *alloc, sl_bench *out, sl_error *err);
/* Release a bench, its cullers, oracle and records. NULL is ignored. */
SL_API void sl_bench_destroy(sl_bench bench);
/* Add a method whose results the caller submits; its index is returned. Only before the first
 * frame. */
SL_API sl_status sl_bench_add_external(sl_bench bench, const char *name, sl_cull_guarantee guarantee,
                                       uint32_t *out_index, sl_error *err);

/* ---- running ---- */

/* Run one frame: render the oracle for cam (its viewport replaced by the options' when set), then
 * every culler method, judging each against the oracle. External methods' records stay invalid
 * until sl_bench_submit. A camera whose eye is outside the domain (the oracle flags it: a BSP leaf
 * without a cluster) gives a frame marked out_of_domain: it is counted and skipped (no method runs,
 * every record stays invalid, reports list it as skipped). */
SL_API sl_status sl_bench_run_frame(sl_bench bench, const sl_camera *cam, sl_error *err);
/* Run one frame from a view (view.h: e.g. an engine's matrices, sl_view_from_matrices) as
 * sl_bench_run_frame does from a camera (a view of a camera gives the same frame); the options'
 * viewport, when set, replaces the view's (sl_view_with_viewport). The frame's `camera` is then
 * for reports only: the view's eye, axes, near, far and vertical extent. */
SL_API sl_status sl_bench_run_view(sl_bench bench, const sl_view *view, sl_error *err);
/* Run frames first..first+count-1 of a path (count clamped to the path's end); progress reports
 * frames done. */
SL_API sl_status sl_bench_run_path(sl_bench bench, sl_path path, uint32_t first, uint32_t count, sl_error *err);
/* Judge an external method's result for the current (last) frame: ids strictly ascending, each
 * below the scene's object count; cull_ms is reported as its time. On a frame outside the domain
 * the result is checked and kept as the last result but not judged (the record stays invalid). */
SL_API sl_status sl_bench_submit(sl_bench bench, uint32_t method, const uint32_t *ids, uint32_t count,
                                 double cull_ms, sl_error *err);

/* ---- results ---- */

/* The scene the bench judges (borrowed: valid while the bench lives), its label, and the number of
 * methods added so far. */
SL_API sl_scene sl_bench_scene(sl_bench bench);
SL_API const char *sl_bench_label(sl_bench bench);
SL_API uint32_t sl_bench_method_count(sl_bench bench);
/* Method `index`; SL_ERROR_INVALID_ARGUMENT beyond the count. */
SL_API sl_status sl_bench_method(sl_bench bench, uint32_t index, sl_bench_method_info *out, sl_error *err);
/* Set the options string that sl_bench_method and every report show for method `index` (by
 * default its effective options, "" for an external method), e.g. a file option named as the file
 * will be found once the caller has moved the run's outputs into place. Copied; no culler changes.
 * SL_ERROR_INVALID_ARGUMENT beyond the count. */
SL_API sl_status sl_bench_set_shown_options(sl_bench bench, uint32_t index, const char *options, sl_error *err);
SL_API uint32_t sl_bench_frame_count(sl_bench bench);
/* Frame `index`; SL_ERROR_INVALID_ARGUMENT beyond the count. */
SL_API sl_status sl_bench_get_frame(sl_bench bench, uint32_t index, sl_bench_frame *out, sl_error *err);
/* The record of method `method` on frame `frame`. */
SL_API sl_status sl_bench_get_record(sl_bench bench, uint32_t frame, uint32_t method, sl_bench_record *out,
                                     sl_error *err);
/* The ids kept by a method on the last frame (valid until the next frame); count 0 before one. */
SL_API sl_status sl_bench_last_result(sl_bench bench, uint32_t method, const uint32_t **ids, uint32_t *count,
                                      sl_error *err);
/* The oracle's answer for the last frame (valid until the next frame or map). */
SL_API sl_status sl_bench_last_truth(sl_bench bench, sl_oracle_frame *out, sl_error *err);
/* A recommendation for the bench's scene and views (the summaries end with its text): among the
 * methods whose guarantee keeps every visible object (conservative, or conservative at the
 * resolution) and that missed nothing, `fastest` is the one of least median cull time whose
 * over-estimation (ratio of sums) is at most max_overestimation, `tightest` the one of least
 * over-estimation whose median cull time is at most max_ms (indices of sl_bench_method, -1 when
 * none qualifies); text says which and why in one paragraph. Bounds from the bench's options. */
typedef struct sl_bench_recommendation {
    int32_t fastest, tightest;
    double max_overestimation, max_ms; /* the bounds used */
    char text[1024];
} sl_bench_recommendation;
SL_API sl_status sl_bench_recommend(sl_bench bench, sl_bench_recommendation *out, sl_error *err);

/* Summary of one method over all frames. */
SL_API sl_status sl_bench_summarize(sl_bench bench, uint32_t method, sl_bench_summary *out, sl_error *err);
/* The ranked columns of the summary table, for sl_bench_best_columns. */
typedef enum sl_bench_column {
    SL_BENCH_COL_OBJECTS,          /* objects drawn (mean per frame) */
    SL_BENCH_COL_TRIANGLES,        /* triangles drawn (mean per frame) */
    SL_BENCH_COL_OVERESTIMATION,   /* over-estimation (ratio of sums) */
    SL_BENCH_COL_MISSED_OBJECTS,   /* missed objects (total) */
    SL_BENCH_COL_MISSED_PIXELS,    /* missed pixels (total) */
    SL_BENCH_COL_MS_MEDIAN,        /* cull ms, median over the frames */
    SL_BENCH_COL_MS_P95,           /* cull ms, 95th percentile */
    SL_BENCH_COL_MS_MAX,           /* cull ms, maximum */
    SL_BENCH_COLUMN_COUNT
} sl_bench_column;

/* The columns in which `method` holds the best value of the bench's methods, as bits (1u << col):
 * the fewest objects and triangles drawn and the least over-estimation among the methods that
 * missed nothing (dropping objects is not a way to be tight), the fewest missed objects and pixels
 * and the shortest cull times among all, each compared as the summary table prints it. Every tie
 * counts; a column in which every method prints the same value has no best. Methods without a
 * judged frame take no part. 0 for an unknown bench or method. The summary tables of
 * sl_bench_print_summary and sl_bench_write_summary print these cells in bold. */
SL_API uint32_t sl_bench_best_columns(sl_bench bench, uint32_t method);
/* Total over every conservative method of the bench of missed objects (0 = the guarantee held). */
SL_API uint64_t sl_bench_violations(sl_bench bench);

/* ---- reports (docs/bench.md has the formats) ---- */

/* Per-frame rows, one per frame x method, of one or more benches, as CSV / as a JSON array of
 * objects with the same fields (plus missed ids and phases). Written atomically. */
SL_API sl_status sl_bench_write_csv(const sl_bench *benches, uint32_t count, const char *path, sl_error *err);
SL_API sl_status sl_bench_write_json(const sl_bench *benches, uint32_t count, const char *path, sl_error *err);
/* The summary: one Markdown table per bench (scene), a row per method. */
SL_API void sl_bench_print_summary(const sl_bench *benches, uint32_t count, FILE *out);
SL_API sl_status sl_bench_write_summary(const sl_bench *benches, uint32_t count, const char *path, sl_error *err);
/* Print one loud line per frame in which a conservative method dropped a visible object:
 * "CONSERVATIVENESS VIOLATION: scene S, frame F: method M (conservative) missed N objects (P pixels):
 * object ID (PX px), ...", at most max_lines lines per method and bench (then a count of the rest).
 * Returns the number of missed objects found, as sl_bench_violations summed over the benches. */
SL_API uint64_t sl_bench_print_violations(const sl_bench *benches, uint32_t count, uint32_t max_lines, FILE *out);
/* SVG line plots of the bench's frames, written to <prefix>cull-time.svg (per-frame cull time per
 * method), <prefix>triangles.svg (triangles drawn per method, with the exact visible set's
 * triangles as a dashed reference) and <prefix>missed-pixels.svg. */
SL_API sl_status sl_bench_write_plots(sl_bench bench, const char *prefix, sl_error *err);

/* Where the top-down map looks from: a camera (its frustum) or a point (a cube map). */
typedef struct sl_bench_map_options {
    bool use_eye;             /* true: visibility from eye in all directions (cube map and the
                                 union of the methods over the six face cameras) */
    sl_vec3 eye;
    sl_camera camera;         /* when !use_eye: visibility from this camera */
    uint32_t size;            /* pixels along the map's longer side, 16..8192 (0: 1024) */
    uint32_t cube_size;       /* cube face size for use_eye, 16..4096 (0: 512) */
    /* also a thumbnail of each map at <prefix><method>-thumb.png, this many pixels along its
     * longer side (each pixel the mean of the map's pixels it covers), 16..size; 0: none. Appended */
    uint32_t thumb_size;
} sl_bench_map_options;

/* Counts of one method's top-down map. */
typedef struct sl_bench_map_counts {
    uint32_t visible_kept;    /* green: visible and kept */
    uint32_t missed;          /* red: visible and dropped */
    uint32_t extra;           /* orange: kept but hidden or outside */
    uint32_t culled;          /* grey: dropped and not visible */
} sl_bench_map_counts;

/* Top-down maps of the scene coloured by visibility from the chosen viewpoint, one PNG per method
 * at <prefix><method>.png: visible and kept (green), visible but dropped (red, also ringed),
 * kept but not visible (orange), dropped and not visible (grey); ground and water paler; lighter
 * is higher; the camera in black (its frustum's horizontal wedge, or a ring around the eye).
 * counts (may be NULL) receives method_count entries (external methods get no map and zero
 * counts). Runs the methods once more (after the frames: it does not change the records, but the
 * last result and truth are the map's afterwards). */
SL_API sl_status sl_bench_write_maps(sl_bench bench, const sl_bench_map_options *opt, const char *prefix,
                                     sl_bench_map_counts *counts, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

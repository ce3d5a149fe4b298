/* Sightline ground truth: the exact point oracle and the metrics that judge every culler.
 *
 * The point oracle rasterizes every triangle of every object whose box meets the view frustum into
 * a 32-bit object-id buffer and a 32-bit float depth buffer, in software, and reports which objects
 * own at least one pixel and how many. The answer is exact at the chosen resolution: an object is
 * visible when some pixel centre sees it first. Rules (docs/oracle.md has the detail):
 *  - coverage: a pixel belongs to a triangle when its centre lies inside the triangle snapped to
 *    1/256 pixel, with the top-left rule deciding centres exactly on an edge, so triangles that
 *    share an edge never leave a gap and never cover a pixel twice;
 *  - clipping: homogeneous clipping against the near and far planes (and a far-away guard band);
 *  - depth: reversed depth (1 - z_ndc)/2, 1 at the near plane and 0 at the far plane, interpolated
 *    in screen space (exact for both projections); the nearest fragment wins and an exact tie goes
 *    to the lower object id, so the image does not depend on the order of drawing;
 *  - faces: both sides of every triangle are drawn, except for objects flagged
 *    SL_OBJECT_CLOSED_CONVEX, whose back faces are skipped (option below);
 *  - maps (BSP data): an object counts only when a sight line to one of its pixels, from the near
 *    plane to its surface, never enters solid space (a leaf without a cluster) from open space;
 *    the id buffer still shows what was drawn. The pixel count of an object that passes is all
 *    its drawn pixels (an upper bound);
 *  - threads: objects are dealt to threads by a fixed rule, each thread draws into its own buffer
 *    and the buffers are merged with the depth rule, so the result is identical bit for bit
 *    whatever the thread count.
 * Cube maps render six 90-degree square faces from a point with exact axis-aligned matrices, so
 * every direction falls into exactly one pixel of exactly one face.
 *
 * The domain (docs/oracle.md, "One set of rules", shared with the region oracle of region.h): in a
 * scene with BSP data (a Quake III map), an eye in a leaf without a cluster (cluster < 0: solid
 * brush or the sealed void outside the playable space) is OUTSIDE THE DOMAIN. There the drawn
 * faces are not a closed world (undrawn "caulk" faces, no brushes), so no image is the truth: the
 * oracle still renders (for display) but flags the frame out_of_domain, the bench skips such
 * frames and every culler returns its frustum set, flagged in sl_cull_stats.out_of_domain.
 *
 * An oracle reads the scene at each render (transforms may change between renders) and must not
 * outlive it. One oracle is used by one thread at a time; it starts its own helper threads.
 */
#ifndef SIGHTLINE_TRUTH_H
#define SIGHTLINE_TRUTH_H

#include "core.h"
#include "geom.h"
#include "scene.h"
#include "camera.h"
#include "view.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_oracle_t *sl_oracle;

/* Largest width or height of an oracle view, and largest pixel count of one view. */
#define SL_ORACLE_MAX_SIZE 16384u
#define SL_ORACLE_MAX_PIXELS (1u << 26)
/* Largest number of rendering threads. */
#define SL_ORACLE_MAX_THREADS SL_MAX_THREADS /* the one thread limit (core.h) */

/* Where the oracle samples each pixel (docs/oracle.md, "Supersampling"). Every pattern renders one
 * pass per sample position, the same position in every pixel, with the camera's own view and
 * projection moved by a sub-pixel offset; the visible set is the union over the passes and the
 * pixel counts are sample counts. */
typedef enum sl_oracle_samples {
    SL_ORACLE_SAMPLES_CENTER = 0, /* one sample at the pixel centre (x + 0.5, y + 0.5): the default */
    SL_ORACLE_SAMPLES_MSAA4 = 1,  /* the standard 4x MSAA positions of D3D and OpenGL, in pixel units
                                     from the top-left corner: (0.375, 0.125), (0.875, 0.375),
                                     (0.125, 0.625), (0.625, 0.875) */
    SL_ORACLE_SAMPLES_JITTER = 2  /* sample_count positions drawn uniformly in the pixel square from
                                     jitter_seed (the same seed gives the same positions) */
} sl_oracle_samples;

/* Most samples per pixel (sample passes of one camera render). */
#define SL_ORACLE_MAX_SAMPLES 16u

typedef struct sl_oracle_options {
    uint32_t width, height;   /* resolution of a camera render; 0 and 0: the camera's own width/height */
    uint32_t threads;         /* rendering threads, 1..SL_ORACLE_MAX_THREADS (default 2) */
    bool draw_closed_backfaces; /* false (default): skip back faces of SL_OBJECT_CLOSED_CONVEX objects */
    bool count_overdraw;      /* keep a per-pixel count of covered fragments (depth complexity) */
    bool see_through_solid;   /* false (default): on a map (BSP data), an object counts only when a
                                 sight line to one of its pixels, from the near plane on, never
                                 enters solid space from open space (docs/oracle.md, rule 4); true:
                                 every drawn pixel counts (the region oracle traces its own) */
    sl_oracle_samples samples;  /* sample positions of a camera render (default CENTER); cube maps
                                   always sample pixel centres */
    uint32_t sample_count;      /* JITTER: samples per pixel, 1..SL_ORACLE_MAX_SAMPLES (0: 4) */
    uint64_t jitter_seed;       /* JITTER: seed of the positions */
} sl_oracle_options;

/* The defaults: camera resolution, 2 threads, closed back faces skipped, no overdraw counts, one
 * sample at each pixel centre. */
SL_API sl_oracle_options sl_oracle_default_options(void);

/* What one render found. Arrays belong to the oracle and stay valid until its next render. */
typedef struct sl_oracle_frame {
    uint32_t view_count;          /* 1 for a camera render (one per sample position with
                                     samples_per_pixel > 1), 6 for a cube map */
    uint32_t width, height;       /* size of each view */
    uint32_t visible_count;       /* objects owning at least one pixel */
    const uint32_t *visible;      /* their ids, ascending */
    const uint32_t *pixels;       /* pixels[i]: pixels owned by visible[i] (summed over the views;
                                     samples, with several samples per pixel) */
    uint64_t covered_pixels;      /* pixels (samples) that show some object (summed over the views) */
    uint32_t objects_in_frustum;  /* objects drawn: their box meets the frustum and may cover a
                                     pixel centre (counted once per view; of a supersampled camera
                                     render, those of its first sample pass) */
    uint64_t triangles_in_frustum;/* their triangles, all drawn (counted once per view) */
    double ms;                    /* wall time of the render */
    bool out_of_domain;           /* the eye is outside the domain (sl_oracle_in_domain): the image
                                     follows the drawing rules but is not the truth; judge nothing
                                     against it */
    int32_t eye_leaf;             /* BSP leaf of the eye, -1 without BSP data */
    uint32_t hidden_by_solid;     /* objects drawn but left out by the open-space rule (maps: every
                                     sight line to them enters solid space); their pixels are not
                                     in covered_pixels */
    uint32_t samples_per_pixel;   /* sample positions per pixel of a camera render (1 for a cube map);
                                     view s of the render holds sample s of every pixel */
} sl_oracle_frame;

/* The buffers of one view of the last render. Row 0 is the top of the image; pixel (x, y) is at
 * index y*width + x. ids hold SL_NONE where nothing was drawn; depth holds reversed depth in
 * [0, 1] (0 where nothing was drawn); overdraw is NULL unless count_overdraw was set. */
typedef struct sl_oracle_view {
    uint32_t width, height;
    const uint32_t *ids;
    const float *depth;
    const uint32_t *overdraw;
    sl_mat4 view_proj;            /* the world-to-clip matrix the view was drawn with (for a sample
                                     pass: the camera's, moved so that the pass's pixel centres fall
                                     on the sample position) */
    double sample_x, sample_y;    /* where in its pixel this view sampled ([0, 1), from the top-left
                                     corner; 0.5, 0.5 for pixel centres) */
} sl_oracle_view;

/* Create an oracle for a scene. options and alloc may be NULL (defaults). */
SL_API sl_status sl_oracle_create(sl_scene scene, const sl_oracle_options *options, const sl_allocator *alloc,
                                  sl_oracle *out, sl_error *err);
/* Release an oracle, its buffers and results. NULL is ignored. */
SL_API void sl_oracle_destroy(sl_oracle oracle);

/* Render the scene from a view (view.h: from a camera or an engine's matrices; perspective or
 * orthographic, off-axis, any depth convention) and report the exact visible set. The image is
 * that of the view's normal form (view_proj: unmirrored, front faces counter-clockwise as seen);
 * an infinite far plane is bounded by the scene's box first (sl_view_bound_far). */
SL_API sl_status sl_oracle_render_view(sl_oracle oracle, const sl_view *view, sl_oracle_frame *out, sl_error *err);
/* sl_oracle_render_view of sl_view_from_camera(cam). */
SL_API sl_status sl_oracle_render(sl_oracle oracle, const sl_camera *cam, sl_oracle_frame *out, sl_error *err);

/* Cube-map faces, in this order. Each face is a 90-degree square view from the eye:
 *   face  forward  right  up        face  forward  right  up
 *   +X    +X       -Y     +Z        -X    -X       +Y     +Z
 *   +Y    +Y       +X     +Z        -Y    -Y       -X     +Z
 *   +Z    +Z       -Y     -X        -Z    -Z       -Y     +X
 * i.e. the horizontal faces are the sl_camera views with yaw 0, 90, 180, 270 degrees and the
 * vertical ones pitch +90 and -90 degrees at yaw 0. */
typedef enum sl_cube_face {
    SL_CUBE_POS_X = 0, SL_CUBE_NEG_X = 1, SL_CUBE_POS_Y = 2,
    SL_CUBE_NEG_Y = 3, SL_CUBE_POS_Z = 4, SL_CUBE_NEG_Z = 5
} sl_cube_face;

/* Render the six faces of a cube map of face_size x face_size pixels around eye, with the given
 * near and far distances (0 < near < far). The frame's set is the union over the faces and its
 * pixel counts the sums; sl_oracle_get_view(oracle, face, ...) gives each face's buffers. */
SL_API sl_status sl_oracle_render_cube(sl_oracle oracle, sl_vec3 eye, uint32_t face_size, float near_plane,
                                       float far_plane, sl_oracle_frame *out, sl_error *err);

/* A camera that shows (up to float rounding) what cube face `face` shows; for display and export. */
SL_API sl_camera sl_cube_face_camera(sl_vec3 eye, sl_cube_face face, uint32_t face_size, float near_plane,
                                     float far_plane);

/* Buffers of view `index` (0 for a camera render, the face for a cube map) of the last render.
 * Fails with SL_ERROR_INVALID_ARGUMENT when there is no such view. */
SL_API sl_status sl_oracle_get_view(sl_oracle oracle, uint32_t index, sl_oracle_view *out, sl_error *err);

/* sl_oracle_in_domain (the oracles' and the cullers' domain) is declared in scene.h. */

/* ---- metrics -------------------------------------------------------------------------------- */

/* A culling result judged against the oracle's visible set of the same view. */
typedef struct sl_cull_metrics {
    uint32_t visible_count;       /* |V|: objects the oracle sees */
    uint32_t result_count;        /* |R|: objects the culler kept */
    uint32_t missed_count;        /* |V \ R|: visible objects the culler dropped (conservative: 0) */
    uint64_t missed_pixels;       /* pixels owned by the missed objects */
    uint32_t extra_count;         /* |R \ V|: kept objects that are hidden or outside */
    double overestimation;        /* |R| / max(|V|, 1) */
    uint64_t triangles_rendered;  /* triangles of the objects in R (what a renderer would draw) */
    uint64_t triangles_visible;   /* triangles of the objects in V (what an exact method would draw) */
} sl_cull_metrics;

/* Compare a culling result (object ids, strictly ascending, each < the scene's object count) with
 * an oracle frame. The first missed_capacity missed objects are written to missed_ids and their
 * pixel counts to missed_pixels (both may be NULL when missed_capacity is 0); out->missed_count
 * counts all of them. Fails with SL_ERROR_INVALID_ARGUMENT on an unsorted or out-of-range result. */
SL_API sl_status sl_metrics_compare(sl_scene scene, const sl_oracle_frame *truth, const uint32_t *result,
                                    uint32_t result_count, sl_cull_metrics *out, uint32_t *missed_ids,
                                    uint32_t *missed_pixels, uint32_t missed_capacity, sl_error *err);

/* Summary of a series of measurements (cull times in ms, counts...). */
typedef struct sl_series_summary {
    size_t count;
    double min, max, mean;
    double median;                /* middle value; mean of the two middle values for an even count */
    double p95;                   /* nearest-rank 95th percentile: the ceil(0.95*count)-th smallest */
} sl_series_summary;

/* Summarise n values (n may be 0: all fields 0). Values must be finite. alloc may be NULL; a
 * sorted copy is made, the input is not changed. */
SL_API sl_status sl_series_summarize(const double *values, size_t n, const sl_allocator *alloc,
                                     sl_series_summary *out, sl_error *err);

/* ---- images of a view (written atomically; thread-safe for distinct paths) ---- */

/* PNG of a view's object ids, each object in sl_id_color, black where nothing was drawn. */
SL_API sl_status sl_image_write_ids(const sl_oracle_view *view, const char *path, const sl_allocator *alloc, sl_error *err);
/* Grey PNG of a view's depth as distance from the camera, nearest bright, farthest dark,
 * logarithmic in distance for a perspective camera (linear for orthographic) and normalised to
 * the range the view contains; black where nothing was drawn. The camera gives near, far and
 * projection. */
SL_API sl_status sl_image_write_depth(const sl_oracle_view *view, const sl_camera *cam, const char *path,
                                      const sl_allocator *alloc, sl_error *err);
/* The same image for a view (view.h, from a camera or an engine's matrices): near, far and
 * projection from `v`, which must be the view the oracle rendered, with a finite far plane (a view
 * with an infinite far plane is drawn as its sl_view_bound_far by the scene's bounds: pass that).
 * For sl_view_from_camera(cam) the PNG is byte for byte that of sl_image_write_depth(cam). */
SL_API sl_status sl_image_write_depth_view(const sl_oracle_view *view, const sl_view *v, const char *path,
                                           const sl_allocator *alloc, sl_error *err);
/* PNG of a view's depth complexity (fragments per pixel) on the colour ramp, 0 black and the
 * view's maximum yellow; *max_out (may be NULL) receives that maximum. The view needs its
 * overdraw buffer (oracle option count_overdraw). */
SL_API sl_status sl_image_write_overdraw(const sl_oracle_view *view, const char *path, const sl_allocator *alloc,
                                         uint32_t *max_out, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

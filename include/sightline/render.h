/* Sightline's OpenGL renderer (libsightline_render, an optional target: built when OpenGL and EGL
 * are found, CMake option SL_GL; docs/render.md).
 *
 * One renderer behind headless and windowed use: OpenGL 4.5 core, headless through EGL (the
 * surfaceless platform, Mesa llvmpipe without a GPU; the device platform on a GPU) or on the
 * caller's current context (a GLFW window: the viewer). The renderer draws into framebuffer objects
 * of its own (colour RGBA8, object id R32UI, depth float, reversed-z where GL_ARB_clip_control is
 * there) and `present` copies the colour to the current draw framebuffer.
 *
 * The scene is uploaded once (one vertex and one index buffer, one draw record per object); a frame
 * draws a visible set with one multi-draw-indirect call per pass. It follows the oracle's rules
 * (docs/oracle.md, "The renderer"): the oracle's facing rule, see-through objects
 * (SL_OBJECT_SEE_THROUGH) drawn after the solid ones with depth test and no depth writes, so they
 * never block.
 *
 * Anything decides what is drawn: a list of ids, any sl_culler (sl_renderer_frame), a PVS through
 * the pvs culler, or a query culler driving this renderer's GL draw backend (sl_renderer_backend:
 * GL_SAMPLES_PASSED queries), which draws while it culls.
 *
 * Errors: every call returns SL_OK or a status with an sl_error message; GL errors and KHR_debug
 * messages of high severity fail the call, naming the GL call or the driver's message.
 *
 * Thread safety: a renderer is driven by one thread at a time, the one whose context is current
 * (headless: the renderer makes its context current on that thread in every call). Two renderers
 * are independent. The scene must outlive the renderer; after objects move, sl_renderer_scene_changed
 * updates their transforms.
 */
#ifndef SIGHTLINE_RENDER_H
#define SIGHTLINE_RENDER_H

#include "core.h"
#include "scene.h"
#include "view.h"
#include "cull.h"
#include "backend.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_renderer_t *sl_renderer;

/* Where the GL context comes from. */
typedef enum sl_gl_context_kind {
    SL_GL_CONTEXT_AUTO = 0,        /* headless: an EGL device with a hardware driver if any, else surfaceless */
    SL_GL_CONTEXT_SURFACELESS = 1, /* EGL_MESA_platform_surfaceless (llvmpipe where there is no GPU) */
    SL_GL_CONTEXT_DEVICE = 2,      /* EGL_EXT_platform_device, the first device with a hardware driver */
    SL_GL_CONTEXT_CURRENT = 3      /* the caller's context, current on the calling thread (GL 4.5 core) */
} sl_gl_context_kind;

typedef struct sl_renderer_options {
    uint32_t width, height;        /* framebuffer size in pixels (default 1280 x 720) */
    sl_gl_context_kind context;
    bool debug;                    /* KHR_debug output, synchronous (default true) */
    bool depth_prepass;            /* draw depth first, then colour with GL_EQUAL (default false) */
    bool timer_queries;            /* GL_TIME_ELAPSED per phase (default true) */
    bool textures;                 /* base-colour textures of the scene's materials (default true) */
    float sun_direction[3];        /* towards the sun, world space; zero: the default (0.3, 0.2, 0.93) */
} sl_renderer_options;

/* The defaults above. */
SL_API void sl_renderer_options_default(sl_renderer_options *out);

/* Is the renderer usable here: can a headless context of this kind be made? (A probe: makes a
 * context and releases it; the reason in err when not.) */
SL_API sl_status sl_renderer_probe(sl_gl_context_kind kind, sl_error *err);

/* Create a renderer for a scene and upload it. options and alloc may be NULL (the defaults). */
SL_API sl_status sl_renderer_create(sl_scene scene, const sl_renderer_options *options, const sl_allocator *alloc,
                                    sl_renderer *out, sl_error *err);
/* Release it (and its context when it made one). NULL is ignored. */
SL_API void sl_renderer_destroy(sl_renderer r);

typedef struct sl_renderer_info {
    char vendor[64], renderer[128], version[96]; /* GL_VENDOR, GL_RENDERER, GL_VERSION */
    sl_gl_context_kind context;    /* what was made (AUTO resolved) */
    bool reversed_z;               /* float depth with glClipControl(GL_ZERO_TO_ONE), cleared to 0, GL_GREATER */
    bool timer_queries;
    uint64_t vertex_bytes, index_bytes, texture_bytes; /* uploaded */
    char texture_warning[288];     /* the first base-colour texture that could not be read or decoded
                                      (its material is drawn in its base colour), or "" */
} sl_renderer_info;
/* What the renderer runs on and uploaded (zeroed for NULL). */
SL_API void sl_renderer_get_info(sl_renderer r, sl_renderer_info *out);

/* Change the framebuffer size. */
SL_API sl_status sl_renderer_resize(sl_renderer r, uint32_t width, uint32_t height, sl_error *err);
/* Objects moved (sl_scene_set_object_transform): upload their transforms. */
SL_API sl_status sl_renderer_scene_changed(sl_renderer r, sl_error *err);
/* Draw every object in a colour of the caller's instead of its own or its material's (0xRRGGBBAA,
 * one per object, copied; the alpha is ignored: see-through objects stay see-through), e.g. to
 * highlight a visible set; NULL restores the scene's colours and materials. */
SL_API sl_status sl_renderer_set_colors(sl_renderer r, const uint32_t *rgba, sl_error *err);

/* What a frame cost and drew. Times in milliseconds; GPU times -1 when timer queries are off. */
typedef struct sl_render_frame_stats {
    double frame_ms;               /* wall time from the start of culling to glFinish */
    double cull_ms;                /* the culler's call (a query culler: its traversal, draws included) */
    double draw_ms;                /* CPU time issuing the draws after culling */
    double wait_ms;                /* waiting on query results (query cullers) */
    double finish_ms;              /* glFinish */
    double gpu_draw_ms, gpu_query_ms; /* GL_TIME_ELAPSED of the draws and of the query draws */
    uint32_t objects_drawn;
    uint64_t triangles_drawn;
    uint32_t draw_calls;           /* GL draw calls */
    uint64_t queries;              /* occlusion queries issued */
    uint64_t query_stalls;
    sl_cull_stats cull;            /* the culler's own statistics (zero when no culler) */
} sl_render_frame_stats;

/* What a draw writes. */
typedef enum sl_render_kind {
    SL_RENDER_SHADED = 0,          /* colour: per-object colour or material, directional light, sky */
    SL_RENDER_IDS = 1,             /* object ids (the oracle's id image) and depth */
    SL_RENDER_DEPTH = 2            /* depth only */
} sl_render_kind;

/* Draw a set of objects (any order, duplicates ignored) from a view into the framebuffer: clear,
 * draw, glFinish. stats may be NULL. */
SL_API sl_status sl_renderer_draw(sl_renderer r, const sl_view *view, const uint32_t *ids, uint32_t count,
                                  sl_render_kind kind, sl_render_frame_stats *stats, sl_error *err);

/* One frame decided by a culler: clear, cull (a culler created with this renderer's backend draws
 * while it culls and is not drawn again), draw the result, glFinish. culler NULL: draw every object
 * (no culling). ids (capacity: the scene's object count) and count may be NULL; they receive the
 * culler's ascending ids. */
SL_API sl_status sl_renderer_frame(sl_renderer r, sl_culler culler, const sl_view *view, sl_render_kind kind,
                                   uint32_t *ids, uint32_t *count, sl_render_frame_stats *stats, sl_error *err);

/* Read back the last frame, row 0 at the top. rgba: width*height*4 bytes; ids: width*height
 * (SL_NONE where nothing was drawn); depth: width*height floats in the oracle's convention
 * ((1 - z/w)/2, 0 where nothing was drawn). */
SL_API sl_status sl_renderer_read_rgba(sl_renderer r, uint8_t *rgba, sl_error *err);
SL_API sl_status sl_renderer_read_ids(sl_renderer r, uint32_t *ids, sl_error *err);
SL_API sl_status sl_renderer_read_depth(sl_renderer r, float *depth, sl_error *err);
/* Write the last frame's colour as a PNG (temporary file and rename). */
SL_API sl_status sl_renderer_write_png(sl_renderer r, const char *path, sl_error *err);
/* Copy the colour to the current draw framebuffer (a window's), scaled to width x height. */
SL_API sl_status sl_renderer_present(sl_renderer r, uint32_t width, uint32_t height, sl_error *err);

/* The GL draw backend (backend.h) over this renderer: draws shaded into its framebuffer, queries
 * with GL_SAMPLES_PASSED. Valid while the renderer lives. */
SL_API sl_draw_backend sl_renderer_backend(sl_renderer r);

/* A culler for this renderer: any registered method (one that draws gets this renderer's backend),
 * or a GL-only method of the render layer ("gpu-hiz"). Same option grammar as sl_culler_create. */
SL_API sl_status sl_renderer_create_culler(sl_renderer r, const char *method, const char *options, sl_culler *out,
                                           sl_error *err);
/* The GL-only methods' descriptions (count, then each by index). */
SL_API uint32_t sl_render_method_count(void);
SL_API const sl_cull_method_desc *sl_render_method(uint32_t index);

/* ===== overlays (the viewer): drawn over the last frame, before read-back or present ===== */

/* Objects drawn see-through in a colour (0xRRGGBBAA), e.g. what a frozen culler culled. */
SL_API sl_status sl_renderer_draw_ghosts(sl_renderer r, const sl_view *view, const uint32_t *ids, uint32_t count,
                                         uint32_t rgba, sl_error *err);
/* Line segments (6 floats each: two world points), e.g. a frozen frustum. */
SL_API sl_status sl_renderer_draw_lines(sl_renderer r, const sl_view *view, const float *segments, uint32_t count,
                                        uint32_t rgba, sl_error *err);
/* Text at pixel (x, y) from the top left, `scale` pixels per font unit (1: the font's size). */
SL_API sl_status sl_renderer_draw_text(sl_renderer r, float x, float y, float scale, const char *text, uint32_t rgba,
                                       sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

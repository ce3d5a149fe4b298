/* The renderer's internals (libsightline_render; include/sightline/render.h is the interface).
 * Shared by the files of src/render: renderer.c and context.c (rcore: context, upload, draws,
 * read-back), backend_gl.c and gpu_hiz.c (glq: the GL draw backend and the gpu-hiz culler),
 * overlay.c and window*.c (viewer). docs/render.md says the rules for users.
 *
 * Linking. libsightline_render.so links libsightline.so, whose internal functions are hidden: code
 * in src/render may call the PUBLIC API of the library (SL_API) and header-only internals (struct
 * layouts, static inline helpers such as cull/culler_internal.h's), nothing else, or the shared
 * library fails to link (-Wl,--no-undefined). The static library (the command and the tests link
 * it) would hide such a mistake; the shared one catches it.
 *
 * GL. OpenGL 4.5 core, entry points straight from glvnd's libOpenGL.so (GL_GLEXT_PROTOTYPES; it
 * exports every core 4.5 function, dispatching to the current context's driver), so there is no
 * loader. Every GL object is made with the 4.5 direct-state-access calls (glCreate*, glNamed*).
 *
 * Context. Headless: r->egl_display / r->egl_context, made current (no surface) at the start of
 * every public call by sl_render_enter, which also fails the call on GL errors left over from
 * outside. SL_GL_CONTEXT_CURRENT: the caller's context, nothing made current. Either way, after
 * sl_render_enter the renderer's context is current on the calling thread.
 *
 * Errors. KHR_debug output (synchronous) goes to sl_render_debug_callback, which records the first
 * message of type ERROR or severity HIGH in r->debug_message; sl_render_check(r, what, err) then
 * reads glGetError too and fails with "WHAT: GL_INVALID_ENUM: <driver's message>". Call it after
 * each group of GL calls, naming the group; a helper's code does the same.
 *
 * Depth convention (the oracle's, docs/oracle.md "The renderer"). The view's OpenGL projection is
 * remapped on the CPU (in double) so that clip z' = (w - z) / 2: window depth z'/w is exactly the
 * oracle's reversed depth (1 - z_ndc) / 2 with glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE): 1 at
 * the near plane, 0 at the far one, the clip volume unchanged (0 <= z' <= w is -w <= z <= w). Depth
 * is a 32-bit float attachment cleared to 0, test GL_GREATER (reversed-z). sl_render_view_matrix
 * gives that matrix; every program uses u_view_proj with it, so depth from any pass (a query's
 * boxes included) compares with the renderer's depth. r->reversed_z is false only on a driver
 * without glClipControl (impossible in 4.5 core, kept for the info struct).
 *
 * Facing (the oracle's rule): objects with SL_OBJECT_CLOSED_CONVEX lose their back faces, the
 * others are drawn two-sided; a transform with a negative determinant swaps which winding is the
 * front. So draw records fall in SL_RENDER_GROUPS state groups (r->records[id].group):
 *   SL_RENDER_GROUP_TWO_SIDED    glDisable(GL_CULL_FACE)
 *   SL_RENDER_GROUP_CULL_CCW     glEnable(GL_CULL_FACE), glFrontFace(GL_CCW)
 *   SL_RENDER_GROUP_CULL_CW      glEnable(GL_CULL_FACE), glFrontFace(GL_CW) (mirrored transforms)
 * and each of them once more for see-through objects (+ SL_RENDER_GROUP_SEE_THROUGH), drawn after
 * all solid ones with the depth test on, depth writes off, blending on.
 *
 * Scene upload (once, in sl_renderer_create): every mesh's vertices go to ONE vertex buffer
 * r->vbo (interleaved sl_render_vertex: position, normal, uv) and its indices to ONE index buffer
 * r->ibo (uint32, relative to the mesh's first vertex); instanced meshes are uploaded once. Each
 * object has a draw record (r->records[id]): first_index and index_count into r->ibo, base_vertex
 * of its mesh in r->vbo, its group. Per object, the transform SSBO r->object_ssbo (binding
 * SL_RENDER_OBJECT_BINDING, std430 array of sl_render_object_gpu: the affine rows, the normal
 * matrix rows, colour, flags, material) is what the shaders read; sl_renderer_scene_changed
 * rewrites it.
 *
 * Materials (scene.h): r->material_ssbo (binding SL_RENDER_MATERIAL_BINDING, sl_render_material_gpu
 * per material id, 0 = none) holds the base colour factor, alpha mode and cutoff and the texture's
 * layer in r->texture_array (GL_TEXTURE_2D_ARRAY on unit 0, every distinct base-colour texture
 * decoded with stb_image and resampled to texture_size^2, mipmapped). An object with a material
 * is drawn in base colour x texture(uv) instead of its own colour; SL_ALPHA_MASK discards
 * fragments below the cutoff (alpha test), SL_ALPHA_BLEND blends. Such objects are see-through
 * (the scene sets SL_OBJECT_SEE_THROUGH): they write no depth and no id (the oracle's id image
 * holds solid objects only), drawn after the solid ones, in the shaded pass only.
 *
 * The object id in the shaders. Attribute SL_RENDER_ATTR_ID is an integer vertex attribute with
 * divisor 1 read from r->id_vbo, which holds 0, 1, 2 ... object_count-1; an indirect command's
 * baseInstance = object id makes that attribute the object's id in every vertex of the command
 * (no gl_BaseInstance needed). The vertex shader fetches objects[id] from the SSBO.
 *
 * How a list of ids is drawn: sl_render_draw_ids(r, ids, count, pass, err). It dedupes the ids
 * (r->stamp), orders them ascending (so that on an exact depth tie the lower id, drawn first,
 * keeps the pixel with GL_GREATER: the oracle's tie rule), writes one
 * DrawElementsIndirectCommand per object {index_count, 1, first_index, base_vertex, id} into
 * r->cmds grouped by group (counting sort), uploads them to r->indirect_buffer and issues ONE
 * glMultiDrawElementsIndirect per non-empty group, with the group's state set. The program is the
 * pass's (sl_render_pass: SHADED colour + id, IDS id only, DEPTH depth only); the caller has bound
 * r->fbo, set the view (sl_render_set_view) and cleared. Counts go to r->frame (objects_drawn,
 * triangles_drawn, draw_calls). A backend drawing during a cull calls the same function.
 *
 * Framebuffer: r->fbo with r->color_tex (RGBA8, attachment 0), r->id_tex (R32UI, attachment 1,
 * cleared to SL_NONE), r->depth_tex (GL_DEPTH_COMPONENT32F). Stored bottom row first (GL);
 * read-back flips to row 0 at the top.
 *
 * Frames and culling (sl_renderer_frame): r->in_frame is true from the start of the cull to the
 * end of the draw; a culler created with this renderer's backend (glq's backend_gl.c) sets
 * r->culler_drew = true in its begin_frame while r->in_frame, draws the objects itself (with
 * sl_render_draw_ids, pass SHADED or the frame's pass r->frame_pass), adds its query counts and
 * wait time to r->frame (queries, query_stalls, wait_ms, gpu_query_ms); the frame then draws
 * nothing more. Otherwise the frame draws the culler's ids. The backend's begin_frame must not
 * clear colour/ids when r->in_frame (the frame cleared them; it may clear depth again).
 */
#ifndef SL_RENDER_INTERNAL_H
#define SL_RENDER_INTERNAL_H

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <sightline/render.h>

#define SL_RENDER_ATTR_POSITION 0
#define SL_RENDER_ATTR_NORMAL 1
#define SL_RENDER_ATTR_UV 2
#define SL_RENDER_ATTR_ID 3
#define SL_RENDER_OBJECT_BINDING 0 /* std430 SSBO: sl_render_object_gpu objects[] */
#define SL_RENDER_MATERIAL_BINDING 1 /* std430 SSBO of materials (when the scene has any) */

enum {
    SL_RENDER_GROUP_TWO_SIDED = 0,
    SL_RENDER_GROUP_CULL_CCW = 1,
    SL_RENDER_GROUP_CULL_CW = 2,
    SL_RENDER_GROUP_SEE_THROUGH = 3, /* added to one of the above */
    SL_RENDER_GROUPS = 6
};

typedef enum sl_render_pass {
    SL_RENDER_PASS_SHADED = 0, /* colour (attachment 0) and id (attachment 1), depth */
    SL_RENDER_PASS_IDS = 1,    /* id and depth */
    SL_RENDER_PASS_DEPTH = 2,  /* depth only */
    SL_RENDER_PASS_COUNT = 3
} sl_render_pass;

typedef struct sl_render_vertex {
    float position[3];
    float normal[3];
    float uv[2];
} sl_render_vertex;

/* One object in the SSBO (std430: 8 vec4). */
typedef struct sl_render_object_gpu {
    float model[12];   /* rows of the 3x4 affine transform (world = M * (p, 1)) */
    float normal[12];  /* rows of the inverse transpose of its 3x3 part (4th of each row unused) */
    uint32_t color;    /* 0xRRGGBBAA */
    uint32_t flags;    /* SL_OBJECT_* */
    uint32_t material; /* SL_NONE: the object's colour */
    uint32_t pad;
    uint32_t pad2[4];
} sl_render_object_gpu;

/* One material in the SSBO (std430: 2 vec4). Index 0 is "no material". */
typedef struct sl_render_material_gpu {
    float base_color[4];  /* RGBA factor */
    uint32_t alpha_mode;  /* sl_alpha_mode */
    uint32_t layer;       /* texture layer + 1 in r->texture_array, 0: no texture */
    float alpha_cutoff;
    uint32_t flags;
} sl_render_material_gpu;

typedef struct sl_render_record {
    uint32_t first_index;    /* into r->ibo */
    uint32_t index_count;    /* 3 * triangles */
    int32_t base_vertex;     /* of the object's mesh in r->vbo */
    uint32_t group;          /* SL_RENDER_GROUP_* */
} sl_render_record;

typedef struct sl_render_indirect {
    uint32_t count, instance_count, first_index;
    int32_t base_vertex;
    uint32_t base_instance; /* = object id */
} sl_render_indirect;

typedef struct sl_render_program {
    GLuint program;
    GLint u_view_proj, u_eye, u_sun, u_inv_view_proj;
} sl_render_program;

struct sl_renderer_t {
    sl_allocator alloc;
    sl_scene scene;
    sl_renderer_options opt;
    uint32_t object_count;

    /* context */
    sl_gl_context_kind context;   /* as made (AUTO resolved) */
    bool own_context;
    EGLDisplay egl_display;
    EGLContext egl_context;
    bool reversed_z;
    char vendor[64], renderer_name[128], version[96];

    /* KHR_debug: the first error-type or high-severity message since the last check */
    bool debug_pending;
    char debug_message[400];
    GLDEBUGPROC prev_debug_fn;    /* SL_GL_CONTEXT_CURRENT: the caller's callback, restored at destroy */
    const void *prev_debug_user;

    /* scene */
    GLuint vao;
    GLuint vbo, ibo, id_vbo;      /* vertices (sl_render_vertex), uint32 indices, ids 0..n-1 */
    GLuint object_ssbo;           /* sl_render_object_gpu[object_count] */
    GLuint material_ssbo;         /* sl_render_material_gpu[material_count + 1] (0: none) */
    GLuint texture_array;         /* GL_TEXTURE_2D_ARRAY, one layer per distinct base-colour texture */
    uint32_t material_count, texture_layers, texture_size;
    char texture_warning[288];
    uint32_t *color_override;     /* [object_count] from sl_renderer_set_colors, or NULL */    /* the first texture that could not be decoded (drawn untextured) */
    GLuint indirect_buffer;       /* sl_render_indirect[object_count], rewritten per draw */
    sl_render_record *records;    /* [object_count] */
    uint64_t vertex_bytes, index_bytes, texture_bytes;

    /* programs */
    sl_render_program passes[SL_RENDER_PASS_COUNT];
    sl_render_program sky;
    GLuint sky_vao;               /* empty VAO for the full-screen triangle */

    /* framebuffer */
    uint32_t width, height;
    GLuint fbo, color_tex, id_tex, depth_tex;

    /* view of the current frame: world -> clip with the depth remap, column-major */
    float view_proj[16];
    float inv_view_proj[16];
    float eye[3];

    /* per-draw scratch */
    uint32_t *stamp;              /* [object_count] dedupe marks */
    uint32_t stamp_value;
    uint32_t *scratch_ids;        /* [object_count] */
    sl_render_indirect *cmds;     /* [object_count] */
    uint32_t *frame_ids;          /* [object_count] a frame's culled ids when the caller passes none */

    /* timer queries: [0] draws, [1] query draws */
    GLuint timers[2];
    bool timers_ok;

    /* the frame in progress (sl_renderer_draw / sl_renderer_frame) */
    bool in_frame;                /* between the start of a frame's cull and the end of its draw */
    bool culler_drew;             /* set by a drawing backend during a frame: do not draw again */
    bool depth_equal;             /* solid draws test GL_EQUAL, no depth writes (after a depth pre-pass) */
    sl_render_pass frame_pass;    /* the pass of the frame's kind */
    sl_render_frame_stats frame;  /* counts accumulate here; copied out at the end */

    /* the GL draw backend's objects (backend_gl.c: box program and buffers, the open query), made
     * at its first use; sl_render_queries_release frees them in sl_renderer_destroy */
    struct sl_render_queries *queries;
    /* overlay.c (viewer): the overlays' programs and buffers, made on first use;
     * sl_render_overlay_release frees them in sl_renderer_destroy */
    struct sl_render_overlay *overlay;
};

/* Set err (when not NULL) and return status; printf format. */
sl_status sl_render_fail(sl_error *err, sl_status status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Make the renderer's context current (headless) and fail on GL errors left from outside ("what"
 * names the public call). */
sl_status sl_render_enter(sl_renderer r, const char *what, sl_error *err);
/* Fail with context on a GL error or a recorded KHR_debug message since the last check. */
sl_status sl_render_check(sl_renderer r, const char *what, sl_error *err);
/* The KHR_debug callback (user = the renderer). */
void APIENTRY sl_render_debug_callback(GLenum source, GLenum type, GLuint id, GLenum severity, GLsizei length,
                                         const GLchar *message, const void *user);

/* context.c: make / release the headless context of kind (AUTO: device, then surfaceless). */
sl_status sl_render_context_make(sl_gl_context_kind kind, bool debug, EGLDisplay *display, EGLContext *context,
                                 sl_gl_context_kind *made, sl_error *err);
void sl_render_context_release(EGLDisplay display, EGLContext context);

/* World -> clip of a view with the depth remap above (column-major). */
void sl_render_view_matrix(const sl_view *view, float out[16]);
/* Inverse of a column-major 4x4 matrix (Gauss-Jordan in double); false when singular. */
bool sl_render_invert4(const double m[16], double out[16]);
/* Set the frame's view: r->view_proj, eye, viewport to the framebuffer. */
void sl_render_set_view(sl_renderer r, const sl_view *view);
/* Clear the framebuffer for a pass (colour: sky drawn; ids SL_NONE; depth 0). Binds r->fbo. */
sl_status sl_render_clear(sl_renderer r, sl_render_pass pass, sl_error *err);
/* Draw the objects `ids` (any order, duplicates ignored) with pass `pass` into the bound
 * framebuffer (see the header comment). */
sl_status sl_render_draw_ids(sl_renderer r, const uint32_t *ids, uint32_t count, sl_render_pass pass,
                             sl_error *err);
/* backend_gl.c: release the GL draw backend's objects (GL ones only when gl_current: the
 * renderer's context is current). */
void sl_render_queries_release(sl_renderer r, bool gl_current);
/* materials.c: upload the scene's materials and decode their base-colour textures. */
sl_status sl_render_upload_materials(sl_renderer r, sl_error *err);
/* overlay.c: release the overlays' state (sl_renderer_destroy; gl: its context is current). */
void sl_render_overlay_release(sl_renderer r, bool gl);
/* The renderer's allocator (zeroed memory; free with the size allocated). */
void *sl_render_alloc(sl_renderer r, size_t size);
void sl_render_free(sl_renderer r, void *p, size_t size);
/* Monotonic wall time in seconds. */
double sl_render_now(void);

#endif

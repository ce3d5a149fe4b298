/* The GL draw backend (include/sightline/backend.h) over a renderer, and the renderer's cullers.
 *
 * sl_renderer_backend(r) is a table whose user is the renderer itself; its GL objects (the box
 * program, the unit-cube index buffer and VAO, the box buffer) live in r->queries, made at the
 * first call that needs them and released with the renderer (sl_render_queries_release).
 *
 * The mapping (docs/backend.md, "A GL backend and hoq's guarantee"; docs/gpu-hiz.md):
 *   begin_frame    the matrix remapped to the renderer's reversed depth (z' = (w - z) / 2, as
 *                  sl_render_view_matrix does), the view set on every program; inside
 *                  sl_renderer_frame (r->in_frame) only depth is cleared again and r->culler_drew
 *                  is set (the frame draws nothing more); outside it colour, ids and depth;
 *   draw_objects   sl_render_draw_ids with the frame's pass (SHADED outside a frame): the culler's
 *                  draws are the frame;
 *   query_boxes    a unit cube's 36 indices instanced once per box (corners from gl_VertexID, the
 *                  box from an SSBO), colour and id writes off (no draw buffers), depth writes off,
 *                  depth test GL_GEQUAL (reversed z: "at least as near"), no face culling;
 *   query_objects  the objects' own geometry with the depth program (the same vertex shader,
 *                  `invariant gl_Position`, as the draws), the draws' facing rule, no writes,
 *                  GL_GEQUAL;
 *   queries        glGenQueries names, GL_SAMPLES_PASSED; poll = GL_QUERY_RESULT_AVAILABLE, wait
 *                  = GL_QUERY_RESULT (a stall when it was not available, its time in
 *                  r->frame.wait_ms); end_frame glFlush.
 * Counts go to r->frame (queries, query_stalls, wait_ms). */
#include "render/backend_gl.h"

#include <math.h>
#include <string.h>

struct sl_render_queries {
    GLuint box_program;
    GLint u_view_proj;
    GLuint box_vao, box_ibo, box_ssbo;
    uint32_t box_capacity;   /* boxes the SSBO holds */
    sl_draw_query open;      /* the open query, 0 when none */
    bool in_frame;           /* between begin_frame and end_frame */
};

#define BOX_BINDING 2 /* std430 vec4 boxes[2 * n]: min, max (after the renderer's 0 and 1) */

static const char box_vertex_src[] =
    "#version 450 core\n"
    "layout(std430, binding = 2) readonly buffer Boxes { vec4 boxes[]; };\n"
    "uniform mat4 u_view_proj;\n"
    "invariant gl_Position;\n"
    "void main() {\n"
    "    vec3 lo = boxes[2 * gl_InstanceID].xyz, hi = boxes[2 * gl_InstanceID + 1].xyz;\n"
    "    int k = gl_VertexID;\n" /* corner k: x from bit 0, y bit 1, z bit 2 */
    "    vec3 p = vec3((k & 1) != 0 ? hi.x : lo.x, (k & 2) != 0 ? hi.y : lo.y, (k & 4) != 0 ? hi.z : lo.z);\n"
    "    gl_Position = u_view_proj * vec4(p, 1.0);\n"
    "}\n";
static const char box_fragment_src[] = "#version 450 core\nvoid main() { }\n";

/* the 12 triangles of a box over its corners (both facings are drawn: no culling) */
static const uint32_t g_box_indices[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                           2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};

void sl_render_queries_release(sl_renderer r, bool gl_current)
{
    struct sl_render_queries *q = r->queries;
    if (!q)
        return;
    if (gl_current) {
        if (q->box_program)
            glDeleteProgram(q->box_program);
        GLuint buffers[2] = {q->box_ibo, q->box_ssbo};
        glDeleteBuffers(2, buffers);
        glDeleteVertexArrays(1, &q->box_vao);
    }
    sl_render_free(r, q, sizeof *q);
    r->queries = NULL;
}

static sl_status shader(GLenum kind, const char *src, GLuint *out, sl_error *err)
{
    GLuint s = glCreateShader(kind);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[300] = "";
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        glDeleteShader(s);
        return sl_render_fail(err, SL_ERROR_INTERNAL, "gl backend: the box query shader does not compile: %s", log);
    }
    *out = s;
    return SL_OK;
}

/* The backend's objects, made once. */
static sl_status need_queries(sl_renderer r, sl_error *err)
{
    if (r->queries)
        return SL_OK;
    struct sl_render_queries *q = sl_render_alloc(r, sizeof *q);
    if (!q)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "gl backend: out of memory");
    r->queries = q;
    GLuint vs = 0, fs = 0;
    sl_status st = shader(GL_VERTEX_SHADER, box_vertex_src, &vs, err);
    if (st == SL_OK)
        st = shader(GL_FRAGMENT_SHADER, box_fragment_src, &fs, err);
    if (st == SL_OK) {
        q->box_program = glCreateProgram();
        glAttachShader(q->box_program, vs);
        glAttachShader(q->box_program, fs);
        glLinkProgram(q->box_program);
        GLint ok = 0;
        glGetProgramiv(q->box_program, GL_LINK_STATUS, &ok);
        if (!ok)
            st = sl_render_fail(err, SL_ERROR_INTERNAL, "gl backend: the box query program does not link");
        q->u_view_proj = glGetUniformLocation(q->box_program, "u_view_proj");
    }
    if (vs)
        glDeleteShader(vs);
    if (fs)
        glDeleteShader(fs);
    if (st == SL_OK) {
        glCreateBuffers(1, &q->box_ibo);
        glNamedBufferStorage(q->box_ibo, sizeof g_box_indices, g_box_indices, 0);
        glCreateVertexArrays(1, &q->box_vao);
        glVertexArrayElementBuffer(q->box_vao, q->box_ibo);
        st = sl_render_check(r, "gl backend: making the box query objects", err);
    }
    if (st != SL_OK)
        sl_render_queries_release(r, true);
    return st;
}

/* ---- the table ---- */

void sl_render_facing_state(int facing)
{
    if (facing == SL_RENDER_GROUP_TWO_SIDED) {
        glDisable(GL_CULL_FACE);
    } else {
        glEnable(GL_CULL_FACE);
        glCullFace(GL_BACK);
        glFrontFace(facing == SL_RENDER_GROUP_CULL_CCW ? GL_CCW : GL_CW);
    }
}

/* The frame's view from a world-to-clip matrix (OpenGL clip space): remapped as the renderer's,
 * set on every program with its inverse (the sky) and the eye (lighting's facing). */
static void set_matrix(sl_renderer r, const float world_to_clip[16])
{
    for (int c = 0; c < 4; c++) {
        const float *m = world_to_clip + 4 * c;
        float *o = r->view_proj + 4 * c;
        o[0] = m[0];
        o[1] = m[1];
        o[2] = (float)(0.5 * ((double)m[3] - (double)m[2])); /* z' = (w - z) / 2 (sl_render_view_matrix) */
        o[3] = m[3];
    }
    double d[16], inv[16];
    for (int i = 0; i < 16; i++)
        d[i] = r->view_proj[i];
    if (!sl_render_invert4(d, inv))
        memset(inv, 0, sizeof inv);
    for (int i = 0; i < 16; i++)
        r->inv_view_proj[i] = (float)inv[i];
    /* the eye: the point clip maps to (0, 0, z, 0) (perspective); orthographic: far behind the
     * near plane's centre along the view direction */
    double w = inv[11];
    if (fabs(w) > 1e-12) {
        for (int i = 0; i < 3; i++)
            r->eye[i] = (float)(inv[8 + i] / w);
    } else {
        double nw = inv[8 + 3] + inv[12 + 3], fw = inv[12 + 3];
        for (int i = 0; i < 3; i++) {
            double near_c = (inv[8 + i] + inv[12 + i]) / nw, far_c = inv[12 + i] / fw;
            r->eye[i] = (float)(near_c + 1e4 * (near_c - far_c));
        }
    }
    for (int p = 0; p < SL_RENDER_PASS_COUNT; p++) {
        sl_render_program *pr = &r->passes[p];
        glProgramUniformMatrix4fv(pr->program, pr->u_view_proj, 1, GL_FALSE, r->view_proj);
        if (pr->u_eye >= 0)
            glProgramUniform3fv(pr->program, pr->u_eye, 1, r->eye);
        if (pr->u_sun >= 0)
            glProgramUniform3fv(pr->program, pr->u_sun, 1, r->opt.sun_direction);
    }
    glProgramUniformMatrix4fv(r->sky.program, r->sky.u_inv_view_proj, 1, GL_FALSE, r->inv_view_proj);
    glProgramUniformMatrix4fv(r->queries->box_program, r->queries->u_view_proj, 1, GL_FALSE, r->view_proj);
    glViewport(0, 0, (GLsizei)r->width, (GLsizei)r->height);
}

static sl_status need_frame(sl_renderer r, const char *what, sl_error *err)
{
    if (!r->queries || !r->queries->in_frame)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: %s outside a frame", what);
    return SL_OK;
}

static sl_status gl_begin_frame(void *user, const float world_to_clip[16], uint32_t width, uint32_t height,
                                sl_error *err)
{
    sl_renderer r = user;
    sl_status st = sl_render_enter(r, "gl backend: begin_frame", err);
    if (st != SL_OK || (st = need_queries(r, err)) != SL_OK)
        return st;
    struct sl_render_queries *q = r->queries;
    if (q->in_frame)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: begin_frame inside a frame");
    if (width != r->width || height != r->height)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT,
                              "gl backend: the view is %ux%u but the renderer's framebuffer is %ux%u "
                              "(sl_renderer_resize)", width, height, r->width, r->height);
    set_matrix(r, world_to_clip);
    if (r->in_frame) {
        /* sl_renderer_frame cleared colour and ids: depth again, the frame is this culler's */
        const GLfloat zero = 0.0f;
        glDepthMask(GL_TRUE);
        glClearNamedFramebufferfv(r->fbo, GL_DEPTH, 0, &zero);
        r->culler_drew = true;
        st = sl_render_check(r, "gl backend: begin_frame", err);
    } else {
        memset(&r->frame, 0, sizeof r->frame);
        r->frame.gpu_draw_ms = r->frame.gpu_query_ms = -1.0;
        st = sl_render_clear(r, SL_RENDER_PASS_SHADED, err);
    }
    if (st == SL_OK)
        q->in_frame = true;
    return st;
}

static sl_status gl_draw_objects(void *user, const uint32_t *ids, uint32_t count, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = need_frame(r, "draw_objects", err);
    if (st != SL_OK)
        return st;
    return sl_render_draw_ids(r, ids, count, r->in_frame ? r->frame_pass : SL_RENDER_PASS_SHADED, err);
}

static sl_status gl_create_queries(void *user, uint32_t count, sl_draw_query *out, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = sl_render_enter(r, "gl backend: create_queries", err);
    if (st != SL_OK)
        return st;
    if (count && !out)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: create_queries: out is NULL");
    GLuint *names = out; /* sl_draw_query is a GLuint */
    glGenQueries((GLsizei)count, names);
    return sl_render_check(r, "gl backend: glGenQueries", err);
}

static void gl_destroy_queries(void *user, const sl_draw_query *queries, uint32_t count)
{
    sl_renderer r = user;
    if (!queries || !count || sl_render_enter(r, "gl backend: destroy_queries", NULL) != SL_OK)
        return;
    glDeleteQueries((GLsizei)count, queries);
    sl_render_check(r, "gl backend: glDeleteQueries", NULL);
}

static sl_status gl_begin_query(void *user, sl_draw_query q, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = need_frame(r, "begin_query", err);
    if (st != SL_OK)
        return st;
    if (r->queries->open)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: begin_query(%u) while query %u is open", q,
                              r->queries->open);
    if (q == 0)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: begin_query: query 0 is not a query");
    glBeginQuery(GL_SAMPLES_PASSED, q);
    if ((st = sl_render_check(r, "gl backend: glBeginQuery(GL_SAMPLES_PASSED)", err)) != SL_OK)
        return st;
    r->queries->open = q;
    r->frame.queries++;
    return SL_OK;
}

/* the state of a query draw: depth test "at least as near", no writes anywhere */
static void query_state(sl_renderer r)
{
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    static const GLenum none[2] = {GL_NONE, GL_NONE};
    glNamedFramebufferDrawBuffers(r->fbo, 2, none);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GEQUAL);
    glDepthMask(GL_FALSE);
    glDisablei(GL_BLEND, 0);
}

static void restore_state(void)
{
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_GREATER);
}

static sl_status gl_query_boxes(void *user, const sl_aabb *boxes, uint32_t count, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = need_frame(r, "query_boxes", err);
    if (st != SL_OK)
        return st;
    if (!r->queries->open)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: query_boxes with no open query");
    if (count && !boxes)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: query_boxes: boxes is NULL");
    if (!count)
        return SL_OK;
    struct sl_render_queries *q = r->queries;
    if (count > q->box_capacity) {
        uint32_t cap = q->box_capacity ? q->box_capacity : 64;
        while (cap < count)
            cap *= 2;
        if (q->box_ssbo)
            glDeleteBuffers(1, &q->box_ssbo);
        glCreateBuffers(1, &q->box_ssbo);
        glNamedBufferStorage(q->box_ssbo, (GLsizeiptr)cap * 32, NULL, GL_DYNAMIC_STORAGE_BIT);
        q->box_capacity = cap;
    }
    /* vec4 pairs, in chunks through a stack buffer */
    float chunk[64 * 8];
    for (uint32_t at = 0; at < count;) {
        uint32_t k = count - at < 64 ? count - at : 64;
        for (uint32_t i = 0; i < k; i++) {
            const sl_aabb *b = &boxes[at + i];
            float *o = chunk + 8 * i;
            o[0] = b->min.x, o[1] = b->min.y, o[2] = b->min.z, o[3] = 1.0f;
            o[4] = b->max.x, o[5] = b->max.y, o[6] = b->max.z, o[7] = 1.0f;
        }
        glNamedBufferSubData(q->box_ssbo, (GLintptr)at * 32, (GLsizeiptr)k * 32, chunk);
        at += k;
    }
    query_state(r);
    glDisable(GL_CULL_FACE);
    glUseProgram(q->box_program);
    glBindVertexArray(q->box_vao);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, BOX_BINDING, q->box_ssbo);
    glDrawElementsInstanced(GL_TRIANGLES, 36, GL_UNSIGNED_INT, NULL, (GLsizei)count);
    r->frame.draw_calls++;
    restore_state();
    return sl_render_check(r, "gl backend: query_boxes (glDrawElementsInstanced)", err);
}

static sl_status gl_query_objects(void *user, const uint32_t *ids, uint32_t count, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = need_frame(r, "query_objects", err);
    if (st != SL_OK)
        return st;
    if (!r->queries->open)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: query_objects with no open query");
    if (count && !ids)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: query_objects: ids is NULL");
    for (uint32_t i = 0; i < count; i++)
        if (ids[i] >= r->object_count)
            return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT,
                                  "gl backend: query_objects: id %u is not an object (the scene has %u)", ids[i],
                                  r->object_count);
    query_state(r);
    glUseProgram(r->passes[SL_RENDER_PASS_DEPTH].program);
    glBindVertexArray(r->vao);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, r->indirect_buffer);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SL_RENDER_OBJECT_BINDING, r->object_ssbo);
    /* each facing group in one multi-draw (see-through objects count like the others: they are
     * seen), chunks of the scratch's size; duplicates are drawn (and counted) again, as GL would */
    for (int facing = 0; facing < SL_RENDER_GROUP_SEE_THROUGH; facing++) {
        uint32_t k = 0;
        for (uint32_t i = 0; i <= count; i++) {
            if (i < count) {
                const sl_render_record *rec = &r->records[ids[i]];
                if (!rec->index_count || (int)(rec->group % SL_RENDER_GROUP_SEE_THROUGH) != facing)
                    continue;
                sl_render_indirect *c = &r->cmds[k++];
                c->count = rec->index_count;
                c->instance_count = 1;
                c->first_index = rec->first_index;
                c->base_vertex = rec->base_vertex;
                c->base_instance = ids[i];
            }
            if (k && (i == count || k == r->object_count)) {
                sl_render_facing_state(facing);
                glNamedBufferSubData(r->indirect_buffer, 0, (GLsizeiptr)(k * sizeof(sl_render_indirect)), r->cmds);
                glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, NULL, (GLsizei)k, 0);
                r->frame.draw_calls++;
                k = 0;
            }
        }
    }
    restore_state();
    return sl_render_check(r, "gl backend: query_objects (glMultiDrawElementsIndirect)", err);
}

static sl_status gl_end_query(void *user, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = need_frame(r, "end_query", err);
    if (st != SL_OK)
        return st;
    if (!r->queries->open)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: end_query with no open query");
    glEndQuery(GL_SAMPLES_PASSED);
    r->queries->open = 0;
    return sl_render_check(r, "gl backend: glEndQuery(GL_SAMPLES_PASSED)", err);
}

/* A query that may be read: issued (glIsQuery is false for a name never begun) and not open. */
static sl_status readable(sl_renderer r, sl_draw_query q, const char *what, sl_error *err)
{
    if (r->queries && r->queries->open == q && q)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: %s of query %u while it is open", what, q);
    if (!q || !glIsQuery(q))
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: %s of query %u, never issued", what, q);
    return SL_OK;
}

static sl_status gl_poll_query(void *user, sl_draw_query q, bool *ready, uint64_t *samples, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = readable(r, q, "poll", err);
    if (st != SL_OK)
        return st;
    GLuint avail = 0;
    glGetQueryObjectuiv(q, GL_QUERY_RESULT_AVAILABLE, &avail);
    *ready = avail != 0;
    if (avail) {
        GLuint64 v = 0;
        glGetQueryObjectui64v(q, GL_QUERY_RESULT, &v);
        *samples = v;
    }
    return sl_render_check(r, "gl backend: poll (GL_QUERY_RESULT_AVAILABLE)", err);
}

static sl_status gl_wait_query(void *user, sl_draw_query q, uint64_t *samples, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = readable(r, q, "wait", err);
    if (st != SL_OK)
        return st;
    GLuint avail = 0;
    glGetQueryObjectuiv(q, GL_QUERY_RESULT_AVAILABLE, &avail);
    double t0 = sl_render_now();
    GLuint64 v = 0;
    glGetQueryObjectui64v(q, GL_QUERY_RESULT, &v);
    if (!avail) {
        r->frame.query_stalls++;
        r->frame.wait_ms += (sl_render_now() - t0) * 1e3;
    }
    *samples = v;
    return sl_render_check(r, "gl backend: wait (GL_QUERY_RESULT)", err);
}

static sl_status gl_end_frame(void *user, sl_error *err)
{
    sl_renderer r = user;
    sl_status st = need_frame(r, "end_frame", err);
    if (st != SL_OK)
        return st;
    struct sl_render_queries *q = r->queries;
    q->in_frame = false;
    if (q->open) {
        glEndQuery(GL_SAMPLES_PASSED);
        q->open = 0;
        sl_render_check(r, "gl backend: end_frame", NULL);
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gl backend: end_frame with a query open (closed now)");
    }
    glFlush();
    return sl_render_check(r, "gl backend: end_frame (glFlush)", err);
}

sl_draw_backend sl_renderer_backend(sl_renderer r)
{
    sl_draw_backend t = {SL_DRAW_BACKEND_VERSION, r,           gl_begin_frame, gl_draw_objects,
                         gl_create_queries,       gl_destroy_queries, gl_begin_query, gl_query_boxes,
                         gl_query_objects,        gl_end_query, gl_poll_query,  gl_wait_query,
                         gl_end_frame};
    return t;
}

bool sl_render_backend_of(const sl_draw_backend *b, sl_renderer *out)
{
    if (!b || b->begin_frame != gl_begin_frame || !b->user)
        return false;
    *out = b->user;
    return true;
}

/* ---- cullers of a renderer ---- */

sl_status sl_renderer_create_culler(sl_renderer r, const char *method, const char *options, sl_culler *out,
                                    sl_error *err)
{
    if (!out)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_create_culler: out is NULL");
    *out = NULL;
    if (!r || !method)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_create_culler: renderer or method is NULL");
    sl_draw_backend be = sl_renderer_backend(r);
    sl_culler_params params = {&be, NULL};
    if (strcmp(method, sl_render_method_gpu_hiz.name) == 0)
        return sl_culler_create_from_method(&sl_render_method_gpu_hiz, r->scene, options, &params, &r->alloc, out, err);
    return sl_culler_create_with(method, r->scene, options, sl_cull_method_draws(method) ? &params : NULL, &r->alloc,
                                 out, err);
}

uint32_t sl_render_method_count(void) { return 1; }

const sl_cull_method_desc *sl_render_method(uint32_t index)
{
    return index == 0 ? &sl_render_desc_gpu_hiz : NULL;
}

/* The viewer's overlays (render.h, "overlays"): drawn over the last frame into the renderer's
 * framebuffer (colour attachment only: ids and depth are left as the frame wrote them), so
 * read-back, PNGs and present show them.
 *
 *  text    stb_easy_font (libstb-dev) turns a string into quads in pixel units; they are drawn as
 *          triangles by a small program mapping pixels (from the top left) to clip space, with
 *          blending, no depth test. Bytes outside printable ASCII are drawn as '?'.
 *  lines   world-space segments through the view's matrix (the renderer's depth remap), one pixel
 *          wide, no depth test: always on top.
 *  ghosts  objects drawn with the scene's own buffers (the renderer's VAO, index buffer and object
 *          SSBO) by a program of their own: a translucent fill in the colour's alpha, then their
 *          edges (polygon mode LINE) opaque. Two-sided, depth-tested against the frame's depth
 *          (GL_GEQUAL with reversed-z, pulled toward the eye by a polygon offset) without
 *          writing it: a ghost shows where nothing drawn in the frame is in front of it.
 *
 * The programs and buffers are made on first use (r->overlay) and released by
 * sl_render_overlay_release (render_internal.h). Errors: sl_render_check after each group of GL calls. */
#include "render/render_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include <stb/stb_easy_font.h>

struct sl_render_overlay {
    GLuint ghost_prog, line_prog, text_prog;
    GLint ghost_vp, ghost_color, line_vp, line_color, text_size, text_color;
    GLuint vao2, vbo2; /* text: vec2 pixels */
    GLuint vao3, vbo3; /* lines: vec3 world */
    GLuint indirect;   /* ghosts' sl_render_indirect commands, [object_count] */
    sl_render_indirect *cmds;
    uint8_t *mark;     /* [object_count] duplicate marks */
    float *scratch;    /* stb_easy_font's vertices, then the triangles */
    size_t scratch_bytes;
};

static const char ghost_vs[] =
    "#version 450 core\n"
    "layout(location = 0) in vec3 a_position;\n"
    "layout(location = 3) in uint a_id;\n"
    "struct Obj { vec4 m0, m1, m2, n0, n1, n2; uvec4 info, pad; };\n"
    "layout(std430, binding = 0) readonly buffer Objects { Obj objects[]; };\n"
    "uniform mat4 u_view_proj;\n"
    "void main() {\n"
    "    Obj o = objects[a_id];\n"
    "    vec4 p = vec4(a_position, 1.0);\n"
    "    gl_Position = u_view_proj * vec4(dot(o.m0, p), dot(o.m1, p), dot(o.m2, p), 1.0);\n"
    "}\n";
static const char line_vs[] =
    "#version 450 core\n"
    "layout(location = 0) in vec3 a_position;\n"
    "uniform mat4 u_view_proj;\n"
    "void main() { gl_Position = u_view_proj * vec4(a_position, 1.0); }\n";
static const char text_vs[] =
    "#version 450 core\n"
    "layout(location = 0) in vec2 a_pixel;\n"
    "uniform vec2 u_size;\n"
    "void main() { gl_Position = vec4(a_pixel.x * 2.0 / u_size.x - 1.0, 1.0 - a_pixel.y * 2.0 / u_size.y, 0.0, 1.0); }\n";
static const char color_fs[] =
    "#version 450 core\n"
    "uniform vec4 u_color;\n"
    "layout(location = 0) out vec4 o_color;\n"
    "void main() { o_color = u_color; }\n";

static sl_status compile(const char *vs, const char *name, GLuint *out, sl_error *err)
{
    const char *src[2] = {vs, color_fs};
    GLenum kinds[2] = {GL_VERTEX_SHADER, GL_FRAGMENT_SHADER};
    GLuint prog = glCreateProgram(), sh[2] = {0, 0};
    char log[512];
    GLint ok = 0;
    for (int i = 0; i < 2; i++) {
        sh[i] = glCreateShader(kinds[i]);
        glShaderSource(sh[i], 1, &src[i], NULL);
        glCompileShader(sh[i]);
        glGetShaderiv(sh[i], GL_COMPILE_STATUS, &ok);
        if (!ok) {
            glGetShaderInfoLog(sh[i], sizeof log, NULL, log);
            glDeleteShader(sh[0]);
            glDeleteShader(sh[1]);
            glDeleteProgram(prog);
            return sl_render_fail(err, SL_ERROR_IO, "overlay %s %s shader: %s", name, i ? "fragment" : "vertex", log);
        }
        glAttachShader(prog, sh[i]);
    }
    glLinkProgram(prog);
    glDeleteShader(sh[0]);
    glDeleteShader(sh[1]);
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramInfoLog(prog, sizeof log, NULL, log);
        glDeleteProgram(prog);
        return sl_render_fail(err, SL_ERROR_IO, "overlay %s program: %s", name, log);
    }
    *out = prog;
    return SL_OK;
}

static GLuint make_vao(GLuint *vbo, int components)
{
    GLuint vao;
    glCreateVertexArrays(1, &vao);
    glCreateBuffers(1, vbo);
    glVertexArrayVertexBuffer(vao, 0, *vbo, 0, (GLsizei)(components * sizeof(float)));
    glEnableVertexArrayAttrib(vao, 0);
    glVertexArrayAttribFormat(vao, 0, components, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao, 0, 0);
    return vao;
}

void sl_render_overlay_release(sl_renderer r, bool gl)
{
    struct sl_render_overlay *o = r ? r->overlay : NULL;
    if (!o)
        return;
    if (gl) {
        glDeleteProgram(o->ghost_prog);
        glDeleteProgram(o->line_prog);
        glDeleteProgram(o->text_prog);
        GLuint vaos[2] = {o->vao2, o->vao3}, bufs[3] = {o->vbo2, o->vbo3, o->indirect};
        glDeleteVertexArrays(2, vaos);
        glDeleteBuffers(3, bufs);
    }
    sl_render_free(r, o->cmds, (size_t)r->object_count * sizeof *o->cmds);
    sl_render_free(r, o->mark, r->object_count);
    sl_render_free(r, o->scratch, o->scratch_bytes);
    sl_render_free(r, o, sizeof *o);
    r->overlay = NULL;
}

/* The overlay state, made on first use. */
static sl_status overlay_of(sl_renderer r, struct sl_render_overlay **out, sl_error *err)
{
    if (r->overlay) {
        *out = r->overlay;
        return SL_OK;
    }
    struct sl_render_overlay *o = sl_render_alloc(r, sizeof *o);
    if (!o)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "overlays: out of memory");
    r->overlay = o;
    sl_status st;
    if ((st = compile(ghost_vs, "ghost", &o->ghost_prog, err)) != SL_OK ||
        (st = compile(line_vs, "line", &o->line_prog, err)) != SL_OK ||
        (st = compile(text_vs, "text", &o->text_prog, err)) != SL_OK) {
        sl_render_overlay_release(r, true);
        return st;
    }
    o->ghost_vp = glGetUniformLocation(o->ghost_prog, "u_view_proj");
    o->ghost_color = glGetUniformLocation(o->ghost_prog, "u_color");
    o->line_vp = glGetUniformLocation(o->line_prog, "u_view_proj");
    o->line_color = glGetUniformLocation(o->line_prog, "u_color");
    o->text_size = glGetUniformLocation(o->text_prog, "u_size");
    o->text_color = glGetUniformLocation(o->text_prog, "u_color");
    o->vao2 = make_vao(&o->vbo2, 2);
    o->vao3 = make_vao(&o->vbo3, 3);
    if (r->object_count) {
        glCreateBuffers(1, &o->indirect);
        glNamedBufferData(o->indirect, (GLsizeiptr)((size_t)r->object_count * sizeof(sl_render_indirect)), NULL,
                          GL_DYNAMIC_DRAW);
        o->cmds = sl_render_alloc(r, (size_t)r->object_count * sizeof *o->cmds);
        o->mark = sl_render_alloc(r, r->object_count);
        if (!o->cmds || !o->mark) {
            sl_render_overlay_release(r, true);
            return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "overlays: out of memory");
        }
    }
    if ((st = sl_render_check(r, "overlays: making the programs and buffers", err)) != SL_OK) {
        sl_render_overlay_release(r, true);
        return st;
    }
    *out = o;
    return SL_OK;
}

/* At least `bytes` of scratch. */
static sl_status scratch(sl_renderer r, struct sl_render_overlay *o, size_t bytes, sl_error *err)
{
    if (o->scratch_bytes >= bytes)
        return SL_OK;
    size_t want = bytes < 4096 ? 4096 : bytes + bytes / 2;
    float *p = sl_render_alloc(r, want);
    if (!p)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "overlays: out of memory (%zu bytes)", want);
    sl_render_free(r, o->scratch, o->scratch_bytes);
    o->scratch = p, o->scratch_bytes = want;
    return SL_OK;
}

static void set_color(GLint loc, uint32_t rgba)
{
    glUniform4f(loc, (float)(rgba >> 24) / 255.0f, (float)((rgba >> 16) & 255) / 255.0f,
                (float)((rgba >> 8) & 255) / 255.0f, (float)(rgba & 255) / 255.0f);
}

/* Bind the framebuffer's colour attachment alone, the whole viewport, blending on. */
static void begin(sl_renderer r)
{
    static const GLenum color_only[2] = {GL_COLOR_ATTACHMENT0, GL_NONE};
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, r->fbo);
    glNamedFramebufferDrawBuffers(r->fbo, 2, color_only);
    glViewport(0, 0, (GLsizei)r->width, (GLsizei)r->height);
    glEnablei(GL_BLEND, 0);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDisable(GL_CULL_FACE);
    glDepthMask(GL_FALSE);
}

/* Back to the renderer's usual state (its draws set what they need, this keeps the defaults). */
static void end(sl_renderer r)
{
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    glDisable(GL_POLYGON_OFFSET_FILL);
    glDisable(GL_POLYGON_OFFSET_LINE);
    glDisablei(GL_BLEND, 0);
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(r->reversed_z ? GL_GREATER : GL_LESS);
    glBindVertexArray(0);
    glUseProgram(0);
}

static sl_status check_view(const sl_view *view, const char *what, sl_error *err)
{
    if (!view)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: view is NULL", what);
    sl_error e;
    if (sl_view_validate(view, &e) != SL_OK)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: %s", what, e.message);
    return SL_OK;
}

sl_status sl_renderer_draw_ghosts(sl_renderer r, const sl_view *view, const uint32_t *ids, uint32_t count,
                                         uint32_t rgba, sl_error *err)
{
    static const char what[] = "sl_renderer_draw_ghosts";
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: renderer is NULL", what);
    sl_status st = check_view(view, what, err);
    if (st != SL_OK)
        return st;
    if (count && !ids)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: ids is NULL", what);
    for (uint32_t i = 0; i < count; i++)
        if (ids[i] >= r->object_count)
            return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: object %u is not in the scene (%u objects)",
                                  what, ids[i], r->object_count);
    struct sl_render_overlay *o;
    if ((st = sl_render_enter(r, what, err)) != SL_OK || (st = overlay_of(r, &o, err)) != SL_OK)
        return st;
    if (!count)
        return SL_OK;
    memset(o->mark, 0, r->object_count);
    uint32_t n = 0;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t id = ids[i];
        const sl_render_record *rec = &r->records[id];
        if (o->mark[id] || !rec->index_count)
            continue;
        o->mark[id] = 1;
        o->cmds[n++] = (sl_render_indirect){rec->index_count, 1, rec->first_index, rec->base_vertex, id};
    }
    if (!n)
        return SL_OK;
    float vp[16];
    sl_render_view_matrix(view, vp);
    glNamedBufferSubData(o->indirect, 0, (GLsizeiptr)((size_t)n * sizeof *o->cmds), o->cmds);
    begin(r);
    glUseProgram(o->ghost_prog);
    glUniformMatrix4fv(o->ghost_vp, 1, GL_FALSE, vp);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SL_RENDER_OBJECT_BINDING, r->object_ssbo);
    glBindVertexArray(r->vao);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, o->indirect);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(r->reversed_z ? GL_GEQUAL : GL_LEQUAL);
    /* toward the eye: larger depth with reversed-z */
    float s = r->reversed_z ? 1.0f : -1.0f;
    glEnable(GL_POLYGON_OFFSET_FILL);
    glEnable(GL_POLYGON_OFFSET_LINE);
    glPolygonOffset(s, s * 4);
    set_color(o->ghost_color, rgba);
    glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, NULL, (GLsizei)n, 0);
    glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    set_color(o->ghost_color, rgba | 0xffu);
    glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, NULL, (GLsizei)n, 0);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
    end(r);
    return sl_render_check(r, what, err);
}

sl_status sl_renderer_draw_lines(sl_renderer r, const sl_view *view, const float *segments, uint32_t count,
                                        uint32_t rgba, sl_error *err)
{
    static const char what[] = "sl_renderer_draw_lines";
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: renderer is NULL", what);
    sl_status st = check_view(view, what, err);
    if (st != SL_OK)
        return st;
    if (count && !segments)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: segments is NULL", what);
    if (count > (1u << 24))
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: %u segments (at most 16777216)", what, count);
    for (size_t i = 0; i < (size_t)count * 6; i++)
        if (!isfinite(segments[i]))
            return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: segment %zu has a non-finite coordinate",
                                  what, i / 6);
    struct sl_render_overlay *o;
    if ((st = sl_render_enter(r, what, err)) != SL_OK || (st = overlay_of(r, &o, err)) != SL_OK)
        return st;
    if (!count)
        return SL_OK;
    float vp[16];
    sl_render_view_matrix(view, vp);
    glNamedBufferData(o->vbo3, (GLsizeiptr)((size_t)count * 6 * sizeof(float)), segments, GL_STREAM_DRAW);
    begin(r);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(o->line_prog);
    glUniformMatrix4fv(o->line_vp, 1, GL_FALSE, vp);
    set_color(o->line_color, rgba);
    glBindVertexArray(o->vao3);
    glDrawArrays(GL_LINES, 0, (GLsizei)(count * 2));
    end(r);
    return sl_render_check(r, what, err);
}

sl_status sl_renderer_draw_text(sl_renderer r, float x, float y, float scale, const char *text, uint32_t rgba,
                                       sl_error *err)
{
    static const char what[] = "sl_renderer_draw_text";
    if (!r || !text)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: %s is NULL", what, r ? "text" : "renderer");
    if (!isfinite(x) || !isfinite(y) || !(scale > 0) || !isfinite(scale))
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: x, y must be finite and scale > 0 (%g, %g, %g)",
                              what, (double)x, (double)y, (double)scale);
    size_t len = strlen(text);
    if (len > 65536)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: text of %zu bytes (at most 65536)", what, len);
    struct sl_render_overlay *o;
    sl_status st;
    if ((st = sl_render_enter(r, what, err)) != SL_OK || (st = overlay_of(r, &o, err)) != SL_OK)
        return st;
    if (!len)
        return SL_OK;
    /* The font's table covers printable ASCII only: other bytes become '?'. A glyph is at most its
     * segments' count of quads (the table's h_seg/v_seg ranges), 64 bytes each from stb_easy_font;
     * the scratch holds those vertices, then the triangles (6 vec2 a quad), then the clean text. */
    size_t quads_max = 1;
    for (size_t i = 0; i < len; i++) {
        unsigned char c = (unsigned char)text[i];
        if (c == '\n')
            continue;
        int g = (c >= 32 && c < 127 ? c : '?') - 32;
        quads_max += (size_t)(stb_easy_font_charinfo[g + 1].h_seg - stb_easy_font_charinfo[g].h_seg) +
                     (size_t)(stb_easy_font_charinfo[g + 1].v_seg - stb_easy_font_charinfo[g].v_seg);
    }
    size_t vbytes = quads_max * 64, tbytes = quads_max * 6 * 2 * sizeof(float);
    if ((st = scratch(r, o, vbytes + tbytes + len + 1, err)) != SL_OK)
        return st;
    char *clean = (char *)o->scratch + vbytes + tbytes;
    for (size_t i = 0; i < len; i++) {
        unsigned char c = (unsigned char)text[i];
        clean[i] = (char)(c == '\n' || (c >= 32 && c < 127) ? c : '?');
    }
    clean[len] = '\0';
    int quads = stb_easy_font_print(0, 0, clean, NULL, o->scratch, (int)vbytes);
    float *tri = (float *)((char *)o->scratch + vbytes);
    const float *v = o->scratch; /* 4 vertices of 4 floats a quad: x, y, z, colour */
    static const int corner[6] = {0, 1, 2, 0, 2, 3};
    for (int q = 0; q < quads; q++)
        for (int k = 0; k < 6; k++) {
            const float *p = v + ((size_t)q * 4 + (size_t)corner[k]) * 4;
            tri[((size_t)q * 6 + (size_t)k) * 2 + 0] = x + p[0] * scale;
            tri[((size_t)q * 6 + (size_t)k) * 2 + 1] = y + p[1] * scale;
        }
    if (!quads)
        return SL_OK;
    glNamedBufferData(o->vbo2, (GLsizeiptr)((size_t)quads * 6 * 2 * sizeof(float)), tri, GL_STREAM_DRAW);
    begin(r);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(o->text_prog);
    glUniform2f(o->text_size, (float)r->width, (float)r->height);
    set_color(o->text_color, rgba);
    glBindVertexArray(o->vao2);
    glDrawArrays(GL_TRIANGLES, 0, quads * 6);
    end(r);
    return sl_render_check(r, what, err);
}

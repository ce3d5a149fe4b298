/* The renderer: scene upload, programs, framebuffer, draws of id lists, frames, read-back
 * (render_internal.h describes the state and the conventions). */
#include "render/render_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sightline/image.h>

/* ---- shaders ---- */

static const char *vertex_src =
    "#version 450 core\n"
    "layout(location = 0) in vec3 a_position;\n"
    "layout(location = 1) in vec3 a_normal;\n"
    "layout(location = 2) in vec2 a_uv;\n"
    "layout(location = 3) in uint a_id;\n"
    "struct Obj { vec4 m0, m1, m2, n0, n1, n2; uvec4 info; uvec4 pad; };\n"
    "layout(std430, binding = 0) readonly buffer Objects { Obj objects[]; };\n"
    "uniform mat4 u_view_proj;\n"
    "invariant gl_Position;\n"
    "flat out uint v_id;\n"
    "flat out uint v_color;\n"
    "flat out uint v_flags;\n"
    "flat out uint v_material;\n"
    "out vec3 v_normal;\n"
    "out vec3 v_world;\n"
    "out vec2 v_uv;\n"
    "void main() {\n"
    "    Obj o = objects[a_id];\n"
    "    vec4 p = vec4(a_position, 1.0);\n"
    "    vec3 w = vec3(dot(o.m0, p), dot(o.m1, p), dot(o.m2, p));\n"
    "    gl_Position = u_view_proj * vec4(w, 1.0);\n"
    "    v_normal = vec3(dot(o.n0.xyz, a_normal), dot(o.n1.xyz, a_normal), dot(o.n2.xyz, a_normal));\n"
    "    v_world = w;\n"
    "    v_uv = a_uv;\n"
    "    v_id = a_id;\n"
    "    v_color = o.info.x;\n"
    "    v_flags = o.info.y;\n"
    "    v_material = o.info.z;\n"
    "}\n";

static const char *shaded_fragment_src =
    "#version 450 core\n"
    "flat in uint v_id;\n"
    "flat in uint v_color;\n"
    "flat in uint v_flags;\n"
    "flat in uint v_material;\n"
    "in vec3 v_world;\n"
    "in vec2 v_uv;\n"
    "struct Mat { vec4 color; uvec4 info; };\n" /* info: alpha mode, layer + 1, cutoff bits, flags */
    "layout(std430, binding = 1) readonly buffer Materials { Mat materials[]; };\n"
    "layout(binding = 0) uniform sampler2DArray u_textures;\n"
    "uniform vec3 u_eye;\n"
    "uniform vec3 u_sun;\n"
    "layout(location = 0) out vec4 o_color;\n"
    "layout(location = 1) out uint o_id;\n"
    "void main() {\n"
    /* flat shading: the triangle's own normal (exact for the cities' and maps' planar faces) */
    "    vec3 n = cross(dFdx(v_world), dFdy(v_world));\n"
    "    float len = length(n);\n"
    "    n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);\n"
    "    if (dot(n, u_eye - v_world) < 0.0) n = -n;\n" /* the side facing the eye */
    "    vec4 base = unpackUnorm4x8(v_color).wzyx;\n"  /* 0xRRGGBBAA */
    "    uint mode = (v_flags & 8u) != 0u ? 2u : 0u;\n" /* see-through without a material: blended */
    "    if (v_material != 0u) {\n"
    "        Mat m = materials[v_material];\n"
    "        base = m.color;\n"
    "        if (m.info.y != 0u) base *= texture(u_textures, vec3(v_uv, float(m.info.y - 1u)));\n"
    "        mode = m.info.x;\n"
    "        if (mode == 1u && base.a < uintBitsToFloat(m.info.z)) discard;\n" /* alpha test */
    "    }\n"
    "    if (mode != 2u) base.a = 1.0;\n"
    "    float sun = max(dot(n, u_sun), 0.0);\n"
    "    float sky = 0.5 + 0.5 * n.z;\n"
    "    vec3 c = base.rgb * (0.62 * sun + 0.22 + 0.16 * sky);\n"
    "    o_color = vec4(min(c, vec3(1.0)), base.a);\n"
    "    o_id = v_id;\n"
    "}\n";

static const char *ids_fragment_src =
    "#version 450 core\n"
    "flat in uint v_id;\n"
    "layout(location = 1) out uint o_id;\n"
    "void main() { o_id = v_id; }\n";

static const char *depth_fragment_src =
    "#version 450 core\n"
    "void main() { }\n";

static const char *sky_vertex_src =
    "#version 450 core\n"
    "out vec2 v_ndc;\n"
    "void main() {\n"
    "    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);\n"
    "    v_ndc = p;\n"
    "    gl_Position = vec4(p, 0.0, 1.0);\n"
    "}\n";

static const char *sky_fragment_src =
    "#version 450 core\n"
    "in vec2 v_ndc;\n"
    "uniform mat4 u_inv_view_proj;\n"
    "layout(location = 0) out vec4 o_color;\n"
    "void main() {\n"
    "    vec4 a = u_inv_view_proj * vec4(v_ndc, 1.0, 1.0);\n" /* near plane (reversed depth 1) */
    "    vec4 b = u_inv_view_proj * vec4(v_ndc, 0.5, 1.0);\n"
    "    vec3 d = normalize(b.xyz / b.w - a.xyz / a.w);\n"
    "    vec3 horizon = vec3(0.78, 0.86, 0.95), zenith = vec3(0.30, 0.50, 0.82), below = vec3(0.55, 0.56, 0.58);\n"
    "    vec3 c = d.z >= 0.0 ? mix(horizon, zenith, sqrt(d.z)) : mix(horizon, below, min(-d.z * 4.0, 1.0));\n"
    "    o_color = vec4(c, 1.0);\n"
    "}\n";

static sl_status compile(sl_renderer r, const char *name, const char *vs, const char *fs, sl_render_program *out,
                         sl_error *err)
{
    GLuint shaders[2] = {glCreateShader(GL_VERTEX_SHADER), glCreateShader(GL_FRAGMENT_SHADER)};
    const char *src[2] = {vs, fs};
    char log[300];
    GLuint prog = glCreateProgram();
    for (int i = 0; i < 2; i++) {
        glShaderSource(shaders[i], 1, &src[i], NULL);
        glCompileShader(shaders[i]);
        GLint ok = 0;
        glGetShaderiv(shaders[i], GL_COMPILE_STATUS, &ok);
        if (!ok) {
            glGetShaderInfoLog(shaders[i], sizeof log, NULL, log);
            glDeleteShader(shaders[0]);
            glDeleteShader(shaders[1]);
            glDeleteProgram(prog);
            r->debug_pending = false; /* the log says it */
            glGetError();
            return sl_render_fail(err, SL_ERROR_INTERNAL, "the %s program's %s shader does not compile: %s", name,
                                  i ? "fragment" : "vertex", log);
        }
        glAttachShader(prog, shaders[i]);
    }
    glLinkProgram(prog);
    glDeleteShader(shaders[0]);
    glDeleteShader(shaders[1]);
    GLint ok = 0;
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramInfoLog(prog, sizeof log, NULL, log);
        glDeleteProgram(prog);
        return sl_render_fail(err, SL_ERROR_INTERNAL, "the %s program does not link: %s", name, log);
    }
    out->program = prog;
    out->u_view_proj = glGetUniformLocation(prog, "u_view_proj");
    out->u_eye = glGetUniformLocation(prog, "u_eye");
    out->u_sun = glGetUniformLocation(prog, "u_sun");
    out->u_inv_view_proj = glGetUniformLocation(prog, "u_inv_view_proj");
    char what[80];
    snprintf(what, sizeof what, "building the %s program", name);
    return sl_render_check(r, what, err);
}

/* ---- memory ---- */

void *sl_render_alloc(sl_renderer r, size_t size)
{
    void *p = r->alloc.alloc(r->alloc.user, size ? size : 1, 16);
    if (p)
        memset(p, 0, size);
    return p;
}
void sl_render_free(sl_renderer r, void *p, size_t size)
{
    if (p)
        r->alloc.free(r->alloc.user, p, size ? size : 1);
}

/* ---- options ---- */

void sl_renderer_options_default(sl_renderer_options *out)
{
    memset(out, 0, sizeof *out);
    out->width = 1280;
    out->height = 720;
    out->context = SL_GL_CONTEXT_AUTO;
    out->debug = true;
    out->depth_prepass = false;
    out->timer_queries = true;
    out->textures = true;
}

/* ---- framebuffer ---- */

static void free_framebuffer(sl_renderer r)
{
    if (r->fbo)
        glDeleteFramebuffers(1, &r->fbo);
    GLuint tex[3] = {r->color_tex, r->id_tex, r->depth_tex};
    glDeleteTextures(3, tex);
    r->fbo = r->color_tex = r->id_tex = r->depth_tex = 0;
}

static sl_status make_framebuffer(sl_renderer r, uint32_t w, uint32_t h, const char *what, sl_error *err)
{
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    if (w == 0 || h == 0)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: framebuffer size %ux%u is empty", what, w, h);
    free_framebuffer(r);
    char label[160];
    glCreateTextures(GL_TEXTURE_2D, 1, &r->color_tex);
    glCreateTextures(GL_TEXTURE_2D, 1, &r->id_tex);
    glCreateTextures(GL_TEXTURE_2D, 1, &r->depth_tex);
    /* sizes beyond GL_MAX_TEXTURE_SIZE are left to GL to refuse, so its error reaches the caller */
    glTextureStorage2D(r->color_tex, 1, GL_RGBA8, (GLsizei)w, (GLsizei)h);
    glTextureStorage2D(r->id_tex, 1, GL_R32UI, (GLsizei)w, (GLsizei)h);
    glTextureStorage2D(r->depth_tex, 1, GL_DEPTH_COMPONENT32F, (GLsizei)w, (GLsizei)h);
    snprintf(label, sizeof label, "%s: glTextureStorage2D(%ux%u; GL_MAX_TEXTURE_SIZE %d)", what, w, h, (int)max_size);
    sl_status st = sl_render_check(r, label, err);
    if (st != SL_OK) {
        free_framebuffer(r);
        return st;
    }
    glTextureParameteri(r->color_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(r->color_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glCreateFramebuffers(1, &r->fbo);
    glNamedFramebufferTexture(r->fbo, GL_COLOR_ATTACHMENT0, r->color_tex, 0);
    glNamedFramebufferTexture(r->fbo, GL_COLOR_ATTACHMENT1, r->id_tex, 0);
    glNamedFramebufferTexture(r->fbo, GL_DEPTH_ATTACHMENT, r->depth_tex, 0);
    GLenum status = glCheckNamedFramebufferStatus(r->fbo, GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
        free_framebuffer(r);
        return sl_render_fail(err, SL_ERROR_UNSUPPORTED, "%s: the framebuffer (RGBA8, R32UI, DEPTH32F) is incomplete (0x%x)",
                              what, (unsigned)status);
    }
    r->width = w;
    r->height = h;
    snprintf(label, sizeof label, "%s: framebuffer", what);
    return sl_render_check(r, label, err);
}

/* ---- scene upload ---- */

static void object_gpu(const sl_object_view *ov, sl_render_object_gpu *g, uint32_t *group)
{
    memset(g, 0, sizeof *g);
    const float *m = ov->transform.m;
    memcpy(g->model, m, sizeof g->model);
    /* inverse transpose of the 3x3 part: cofactors / det */
    double a[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            a[i][j] = m[i * 4 + j];
    double cof[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            cof[i][j] = a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1];
        }
    double det = a[0][0] * cof[0][0] + a[0][1] * cof[0][1] + a[0][2] * cof[0][2];
    double s = det != 0.0 ? 1.0 / det : 1.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            g->normal[i * 4 + j] = (float)(cof[i][j] * s);
    g->color = ov->color;
    g->flags = ov->flags;
    g->material = ov->material; /* 0: none */
    uint32_t gr = SL_RENDER_GROUP_TWO_SIDED;
    if (ov->flags & SL_OBJECT_CLOSED_CONVEX)
        gr = det < 0.0 ? SL_RENDER_GROUP_CULL_CW : SL_RENDER_GROUP_CULL_CCW;
    if (ov->flags & SL_OBJECT_SEE_THROUGH)
        gr += SL_RENDER_GROUP_SEE_THROUGH;
    *group = gr;
}

static sl_status upload_objects(sl_renderer r, bool create, sl_error *err)
{
    size_t bytes = (size_t)r->object_count * sizeof(sl_render_object_gpu);
    sl_render_object_gpu *objs = sl_render_alloc(r, bytes);
    if (!objs)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "renderer: %zu bytes for the object buffer", bytes);
    for (uint32_t i = 0; i < r->object_count; i++) {
        sl_object_view ov = sl_scene_object(r->scene, i);
        object_gpu(&ov, &objs[i], &r->records[i].group);
        if (r->color_override) {
            objs[i].color = r->color_override[i] | 0xFFu;
            objs[i].material = 0;
        }
    }
    if (create) {
        glCreateBuffers(1, &r->object_ssbo);
        glNamedBufferStorage(r->object_ssbo, bytes ? (GLsizeiptr)bytes : 16, bytes ? objs : NULL, GL_DYNAMIC_STORAGE_BIT);
    } else if (bytes) {
        glNamedBufferSubData(r->object_ssbo, 0, (GLsizeiptr)bytes, objs);
    }
    sl_render_free(r, objs, bytes);
    return sl_render_check(r, "uploading the object transforms", err);
}

static sl_status upload_scene(sl_renderer r, sl_error *err)
{
    sl_scene s = r->scene;
    uint32_t mesh_count = sl_scene_mesh_count(s);
    size_t mbytes = (size_t)mesh_count * 2 * sizeof(uint64_t);
    uint64_t *mesh_at = sl_render_alloc(r, mbytes); /* [2m]: first vertex + 1 (0: unused), [2m+1]: first index */
    if (!mesh_at)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "renderer: mesh table");
    uint64_t vertices = 0, indices = 0;
    for (uint32_t i = 0; i < r->object_count; i++) {
        uint32_t m = sl_scene_object(s, i).mesh;
        if (m >= mesh_count || mesh_at[2 * m])
            continue;
        sl_mesh_view mv = sl_scene_mesh(s, m);
        mesh_at[2 * m] = vertices + 1;
        mesh_at[2 * m + 1] = indices;
        vertices += mv.vertex_count;
        indices += 3ull * mv.triangle_count;
    }
    if (vertices > (uint64_t)INT32_MAX || indices > (uint64_t)UINT32_MAX ||
        vertices * sizeof(sl_render_vertex) > ((uint64_t)1 << 40)) {
        sl_render_free(r, mesh_at, mbytes);
        return sl_render_fail(err, SL_ERROR_LIMIT, "renderer: the scene's %llu vertices / %llu indices exceed one buffer",
                              (unsigned long long)vertices, (unsigned long long)indices);
    }
    size_t vbytes = (size_t)vertices * sizeof(sl_render_vertex), ibytes = (size_t)indices * 4;
    sl_render_vertex *vb = sl_render_alloc(r, vbytes);
    uint32_t *ib = sl_render_alloc(r, ibytes);
    if (!vb || !ib) {
        sl_render_free(r, vb, vbytes);
        sl_render_free(r, ib, ibytes);
        sl_render_free(r, mesh_at, mbytes);
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "renderer: %zu + %zu bytes of vertices and indices", vbytes,
                              ibytes);
    }
    for (uint32_t m = 0; m < mesh_count; m++) {
        if (!mesh_at[2 * m])
            continue;
        sl_mesh_view mv = sl_scene_mesh(s, m);
        sl_render_vertex *v = vb + (mesh_at[2 * m] - 1);
        for (uint32_t k = 0; k < mv.vertex_count; k++) {
            memcpy(v[k].position, mv.positions + 3 * (size_t)k, 12);
            if (mv.normals)
                memcpy(v[k].normal, mv.normals + 3 * (size_t)k, 12);
            if (mv.uvs)
                memcpy(v[k].uv, mv.uvs + 2 * (size_t)k, 8);
        }
        memcpy(ib + mesh_at[2 * m + 1], mv.indices, 12 * (size_t)mv.triangle_count);
    }
    for (uint32_t i = 0; i < r->object_count; i++) {
        sl_object_view ov = sl_scene_object(s, i);
        sl_render_record *rec = &r->records[i];
        if (ov.mesh >= mesh_count)
            continue;
        sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
        rec->first_index = (uint32_t)mesh_at[2 * ov.mesh + 1];
        rec->index_count = 3 * mv.triangle_count;
        rec->base_vertex = (int32_t)(mesh_at[2 * ov.mesh] - 1);
    }
    sl_render_free(r, mesh_at, mbytes);

    glCreateBuffers(1, &r->vbo);
    glNamedBufferStorage(r->vbo, vbytes ? (GLsizeiptr)vbytes : 16, vbytes ? vb : NULL, 0);
    glCreateBuffers(1, &r->ibo);
    glNamedBufferStorage(r->ibo, ibytes ? (GLsizeiptr)ibytes : 16, ibytes ? ib : NULL, 0);
    sl_render_free(r, vb, vbytes);
    sl_render_free(r, ib, ibytes);
    r->vertex_bytes = vbytes;
    r->index_bytes = ibytes;

    size_t idbytes = (size_t)r->object_count * 4;
    uint32_t *idv = sl_render_alloc(r, idbytes);
    if (!idv)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "renderer: id buffer");
    for (uint32_t i = 0; i < r->object_count; i++)
        idv[i] = i;
    glCreateBuffers(1, &r->id_vbo);
    glNamedBufferStorage(r->id_vbo, idbytes ? (GLsizeiptr)idbytes : 16, idbytes ? idv : NULL, 0);
    sl_render_free(r, idv, idbytes);
    glCreateBuffers(1, &r->indirect_buffer);
    size_t cbytes = (size_t)(r->object_count ? r->object_count : 1) * sizeof(sl_render_indirect);
    glNamedBufferStorage(r->indirect_buffer, (GLsizeiptr)cbytes, NULL, GL_DYNAMIC_STORAGE_BIT);

    glCreateVertexArrays(1, &r->vao);
    GLuint vao = r->vao;
    glVertexArrayVertexBuffer(vao, 0, r->vbo, 0, sizeof(sl_render_vertex));
    glVertexArrayVertexBuffer(vao, 1, r->id_vbo, 0, 4);
    glVertexArrayBindingDivisor(vao, 1, 1);
    glVertexArrayElementBuffer(vao, r->ibo);
    glEnableVertexArrayAttrib(vao, SL_RENDER_ATTR_POSITION);
    glVertexArrayAttribFormat(vao, SL_RENDER_ATTR_POSITION, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao, SL_RENDER_ATTR_POSITION, 0);
    glEnableVertexArrayAttrib(vao, SL_RENDER_ATTR_NORMAL);
    glVertexArrayAttribFormat(vao, SL_RENDER_ATTR_NORMAL, 3, GL_FLOAT, GL_FALSE, 12);
    glVertexArrayAttribBinding(vao, SL_RENDER_ATTR_NORMAL, 0);
    glEnableVertexArrayAttrib(vao, SL_RENDER_ATTR_UV);
    glVertexArrayAttribFormat(vao, SL_RENDER_ATTR_UV, 2, GL_FLOAT, GL_FALSE, 24);
    glVertexArrayAttribBinding(vao, SL_RENDER_ATTR_UV, 0);
    glEnableVertexArrayAttrib(vao, SL_RENDER_ATTR_ID);
    glVertexArrayAttribIFormat(vao, SL_RENDER_ATTR_ID, 1, GL_UNSIGNED_INT, 0);
    glVertexArrayAttribBinding(vao, SL_RENDER_ATTR_ID, 1);
    glCreateVertexArrays(1, &r->sky_vao);
    sl_status st = sl_render_check(r, "uploading the scene's vertex and index buffers", err);
    if (st != SL_OK || (st = sl_render_upload_materials(r, err)) != SL_OK)
        return st;
    return upload_objects(r, true, err);
}

/* ---- create / destroy ---- */

sl_status sl_renderer_create(sl_scene scene, const sl_renderer_options *options, const sl_allocator *alloc,
                             sl_renderer *out, sl_error *err)
{
    if (!out)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_create: out is NULL");
    *out = NULL;
    if (!scene)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_create: scene is NULL");
    if (!alloc)
        alloc = sl_default_allocator();
    sl_renderer r = alloc->alloc(alloc->user, sizeof *r, 16);
    if (!r)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_renderer_create: renderer");
    memset(r, 0, sizeof *r);
    r->alloc = *alloc;
    r->scene = scene;
    if (options)
        r->opt = *options;
    else
        sl_renderer_options_default(&r->opt);
    if (r->opt.width == 0 || r->opt.height == 0) {
        r->opt.width = 1280;
        r->opt.height = 720;
    }
    float *sun = r->opt.sun_direction;
    if (sun[0] == 0.0f && sun[1] == 0.0f && sun[2] == 0.0f) {
        sun[0] = 0.3f;
        sun[1] = 0.2f;
        sun[2] = 0.93f;
    }
    float len = sqrtf(sun[0] * sun[0] + sun[1] * sun[1] + sun[2] * sun[2]);
    for (int i = 0; i < 3; i++)
        sun[i] /= len;
    r->object_count = sl_scene_object_count(scene);
    r->egl_display = EGL_NO_DISPLAY;
    r->egl_context = EGL_NO_CONTEXT;
    sl_status st;
    if (r->opt.context == SL_GL_CONTEXT_CURRENT) {
        r->context = SL_GL_CONTEXT_CURRENT;
        if (!glGetString(GL_VERSION)) {
            alloc->free(alloc->user, r, sizeof *r);
            return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT,
                                  "sl_renderer_create: SL_GL_CONTEXT_CURRENT but no GL context is current");
        }
    } else {
        st = sl_render_context_make(r->opt.context, r->opt.debug, &r->egl_display, &r->egl_context, &r->context, err);
        if (st != SL_OK) {
            alloc->free(alloc->user, r, sizeof *r);
            return st;
        }
        r->own_context = true;
    }
    GLint major = 0, minor = 0, profile = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &profile);
    snprintf(r->vendor, sizeof r->vendor, "%s", (const char *)glGetString(GL_VENDOR));
    snprintf(r->renderer_name, sizeof r->renderer_name, "%s", (const char *)glGetString(GL_RENDERER));
    snprintf(r->version, sizeof r->version, "%s", (const char *)glGetString(GL_VERSION));
    if (major * 10 + minor < 45) {
        st = sl_render_fail(err, SL_ERROR_UNSUPPORTED, "sl_renderer_create: OpenGL 4.5 needed, the context is %d.%d (%s, %s)",
                            (int)major, (int)minor, r->renderer_name, r->version);
        sl_renderer_destroy(r);
        return st;
    }
    if (r->opt.debug) {
        if (!r->own_context) {
            void *fn = NULL, *user = NULL;
            glGetPointerv(GL_DEBUG_CALLBACK_FUNCTION, &fn);
            glGetPointerv(GL_DEBUG_CALLBACK_USER_PARAM, &user);
            r->prev_debug_fn = (GLDEBUGPROC)(uintptr_t)fn;
            r->prev_debug_user = user;
        }
        glEnable(GL_DEBUG_OUTPUT);
        glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
        glDebugMessageCallback(sl_render_debug_callback, r);
        glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DONT_CARE, 0, NULL, GL_TRUE);
    }
    glGetError();
    size_t n = r->object_count ? r->object_count : 1;
    r->records = sl_render_alloc(r, n * sizeof *r->records);
    r->stamp = sl_render_alloc(r, n * 4);
    r->scratch_ids = sl_render_alloc(r, n * 4);
    r->frame_ids = sl_render_alloc(r, n * 4);
    r->cmds = sl_render_alloc(r, n * sizeof *r->cmds);
    if (!r->records || !r->stamp || !r->scratch_ids || !r->frame_ids || !r->cmds) {
        sl_renderer_destroy(r);
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_renderer_create: per-object tables");
    }
    /* reversed-z: the oracle's depth (render_internal.h); core in 4.5 */
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    r->reversed_z = true;
    if ((st = sl_render_check(r, "sl_renderer_create: glClipControl(GL_ZERO_TO_ONE)", err)) != SL_OK ||
        (st = compile(r, "shaded", vertex_src, shaded_fragment_src, &r->passes[SL_RENDER_PASS_SHADED], err)) != SL_OK ||
        (st = compile(r, "id", vertex_src, ids_fragment_src, &r->passes[SL_RENDER_PASS_IDS], err)) != SL_OK ||
        (st = compile(r, "depth", vertex_src, depth_fragment_src, &r->passes[SL_RENDER_PASS_DEPTH], err)) != SL_OK ||
        (st = compile(r, "sky", sky_vertex_src, sky_fragment_src, &r->sky, err)) != SL_OK ||
        (st = upload_scene(r, err)) != SL_OK ||
        (st = make_framebuffer(r, r->opt.width, r->opt.height, "sl_renderer_create", err)) != SL_OK) {
        sl_renderer_destroy(r);
        return st;
    }
    if (r->opt.timer_queries) {
        glCreateQueries(GL_TIME_ELAPSED, 2, r->timers);
        r->timers_ok = sl_render_check(r, "timer queries", NULL) == SL_OK;
    }
    *out = r;
    return SL_OK;
}

void sl_renderer_destroy(sl_renderer r)
{
    if (!r)
        return;
    bool current = !r->own_context || eglMakeCurrent(r->egl_display, EGL_NO_SURFACE, EGL_NO_SURFACE, r->egl_context);
    bool gl = current && (r->own_context || glGetString(GL_VERSION));
    sl_render_queries_release(r, gl);
    sl_render_overlay_release(r, gl);
    if (gl) {
        free_framebuffer(r);
        GLuint buffers[6] = {r->vbo, r->ibo, r->id_vbo, r->object_ssbo, r->indirect_buffer, r->material_ssbo};
        glDeleteBuffers(6, buffers);
        if (r->texture_array)
            glDeleteTextures(1, &r->texture_array);
        GLuint vaos[2] = {r->vao, r->sky_vao};
        glDeleteVertexArrays(2, vaos);
        for (int i = 0; i < SL_RENDER_PASS_COUNT; i++)
            if (r->passes[i].program)
                glDeleteProgram(r->passes[i].program);
        if (r->sky.program)
            glDeleteProgram(r->sky.program);
        if (r->timers[0])
            glDeleteQueries(2, r->timers);
        if (r->opt.debug) /* the caller's callback back on its context (none on ours) */
            glDebugMessageCallback(r->prev_debug_fn, r->prev_debug_user);
    }
    if (r->own_context)
        sl_render_context_release(r->egl_display, r->egl_context);
    size_t n = r->object_count ? r->object_count : 1;
    sl_render_free(r, r->records, n * sizeof *r->records);
    sl_render_free(r, r->stamp, n * 4);
    sl_render_free(r, r->scratch_ids, n * 4);
    sl_render_free(r, r->frame_ids, n * 4);
    sl_render_free(r, r->cmds, n * sizeof *r->cmds);
    sl_render_free(r, r->color_override, n * 4);
    sl_allocator a = r->alloc;
    a.free(a.user, r, sizeof *r);
}

void sl_renderer_get_info(sl_renderer r, sl_renderer_info *out)
{
    memset(out, 0, sizeof *out);
    if (!r)
        return;
    snprintf(out->vendor, sizeof out->vendor, "%s", r->vendor);
    snprintf(out->renderer, sizeof out->renderer, "%s", r->renderer_name);
    snprintf(out->version, sizeof out->version, "%s", r->version);
    out->context = r->context;
    out->reversed_z = r->reversed_z;
    out->timer_queries = r->timers_ok;
    out->vertex_bytes = r->vertex_bytes;
    out->index_bytes = r->index_bytes;
    out->texture_bytes = r->texture_bytes;
    snprintf(out->texture_warning, sizeof out->texture_warning, "%s", r->texture_warning);
}

sl_status sl_renderer_resize(sl_renderer r, uint32_t width, uint32_t height, sl_error *err)
{
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_resize: renderer is NULL");
    sl_status st = sl_render_enter(r, "sl_renderer_resize", err);
    if (st != SL_OK)
        return st;
    if (width == r->width && height == r->height)
        return SL_OK;
    uint32_t ow = r->width, oh = r->height;
    st = make_framebuffer(r, width, height, "sl_renderer_resize", err);
    if (st != SL_OK) {
        sl_error ignored;
        make_framebuffer(r, ow, oh, "sl_renderer_resize (restoring the old size)", &ignored);
    }
    return st;
}

sl_status sl_renderer_scene_changed(sl_renderer r, sl_error *err)
{
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_scene_changed: renderer is NULL");
    sl_status st = sl_render_enter(r, "sl_renderer_scene_changed", err);
    if (st != SL_OK)
        return st;
    if (sl_scene_object_count(r->scene) != r->object_count)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT,
                              "sl_renderer_scene_changed: the scene has %u objects, the renderer was made with %u",
                              sl_scene_object_count(r->scene), r->object_count);
    return upload_objects(r, false, err);
}

sl_status sl_renderer_set_colors(sl_renderer r, const uint32_t *rgba, sl_error *err)
{
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_set_colors: renderer is NULL");
    sl_status st = sl_render_enter(r, "sl_renderer_set_colors", err);
    if (st != SL_OK)
        return st;
    size_t n = r->object_count ? r->object_count : 1;
    if (!rgba) {
        sl_render_free(r, r->color_override, n * 4);
        r->color_override = NULL;
    } else {
        if (!r->color_override && !(r->color_override = sl_render_alloc(r, n * 4)))
            return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_renderer_set_colors: %zu bytes", n * 4);
        memcpy(r->color_override, rgba, (size_t)r->object_count * 4);
    }
    return upload_objects(r, false, err);
}

/* ---- views ---- */

bool sl_render_invert4(const double m[16], double out[16])
{
    double a[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            a[i][j] = m[j * 4 + i]; /* row i, column j of column-major m */
            a[i][j + 4] = i == j ? 1.0 : 0.0;
        }
    for (int c = 0; c < 4; c++) {
        int p = c;
        for (int i = c + 1; i < 4; i++)
            if (fabs(a[i][c]) > fabs(a[p][c]))
                p = i;
        if (a[p][c] == 0.0)
            return false;
        for (int j = 0; j < 8; j++) {
            double t = a[c][j];
            a[c][j] = a[p][j];
            a[p][j] = t;
        }
        double inv = 1.0 / a[c][c];
        for (int j = 0; j < 8; j++)
            a[c][j] *= inv;
        for (int i = 0; i < 4; i++)
            if (i != c) {
                double f = a[i][c];
                for (int j = 0; j < 8; j++)
                    a[i][j] -= f * a[c][j];
            }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            out[j * 4 + i] = a[i][j + 4];
    return true;
}

void sl_render_view_matrix(const sl_view *view, float out[16])
{
    const float *m = view->view_proj.m;
    for (int c = 0; c < 4; c++) {
        out[c * 4 + 0] = m[c * 4 + 0];
        out[c * 4 + 1] = m[c * 4 + 1];
        out[c * 4 + 2] = (float)(0.5 * ((double)m[c * 4 + 3] - (double)m[c * 4 + 2])); /* z' = (w - z) / 2 */
        out[c * 4 + 3] = m[c * 4 + 3];
    }
}

void sl_render_set_view(sl_renderer r, const sl_view *view)
{
    sl_render_view_matrix(view, r->view_proj);
    double d[16], inv[16];
    for (int i = 0; i < 16; i++)
        d[i] = r->view_proj[i];
    if (!sl_render_invert4(d, inv))
        memset(inv, 0, sizeof inv);
    for (int i = 0; i < 16; i++)
        r->inv_view_proj[i] = (float)inv[i];
    r->eye[0] = view->eye.x;
    r->eye[1] = view->eye.y;
    r->eye[2] = view->eye.z;
    for (int p = 0; p < SL_RENDER_PASS_COUNT; p++) {
        sl_render_program *pr = &r->passes[p];
        glProgramUniformMatrix4fv(pr->program, pr->u_view_proj, 1, GL_FALSE, r->view_proj);
        if (pr->u_eye >= 0)
            glProgramUniform3fv(pr->program, pr->u_eye, 1, r->eye);
        if (pr->u_sun >= 0)
            glProgramUniform3fv(pr->program, pr->u_sun, 1, r->opt.sun_direction);
    }
    glProgramUniformMatrix4fv(r->sky.program, r->sky.u_inv_view_proj, 1, GL_FALSE, r->inv_view_proj);
    glViewport(0, 0, (GLsizei)r->width, (GLsizei)r->height);
}

sl_status sl_render_clear(sl_renderer r, sl_render_pass pass, sl_error *err)
{
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    static const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(r->fbo, 2, both);
    const GLuint none[4] = {SL_NONE, 0, 0, 0};
    const GLfloat black[4] = {0, 0, 0, 1}, zero = 0.0f;
    glDepthMask(GL_TRUE);
    glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glClearNamedFramebufferuiv(r->fbo, GL_COLOR, 1, none);
    glClearNamedFramebufferfv(r->fbo, GL_DEPTH, 0, &zero);
    if (pass == SL_RENDER_PASS_SHADED) {
        glDisable(GL_DEPTH_TEST);
        glDisable(GL_CULL_FACE);
        glDisable(GL_BLEND);
        glColorMaski(1, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        glDepthMask(GL_FALSE);
        glUseProgram(r->sky.program);
        glBindVertexArray(r->sky_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        glDepthMask(GL_TRUE);
    } else {
        glClearNamedFramebufferfv(r->fbo, GL_COLOR, 0, black);
    }
    return sl_render_check(r, "clearing the framebuffer", err);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

sl_status sl_render_draw_ids(sl_renderer r, const uint32_t *ids, uint32_t count, sl_render_pass pass, sl_error *err)
{
    if (count && !ids)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "draw: ids is NULL");
    if (++r->stamp_value == 0) {
        memset(r->stamp, 0, (size_t)r->object_count * 4);
        r->stamp_value = 1;
    }
    uint32_t n = 0, prev = 0;
    bool sorted = true;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t id = ids[i];
        if (id >= r->object_count)
            return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "draw: id %u is not an object (the scene has %u)", id,
                                  r->object_count);
        if (r->stamp[id] == r->stamp_value)
            continue;
        r->stamp[id] = r->stamp_value;
        if (n && id < prev)
            sorted = false;
        prev = id;
        r->scratch_ids[n++] = id;
    }
    if (!sorted)
        qsort(r->scratch_ids, n, 4, cmp_u32);
    uint32_t at[SL_RENDER_GROUPS + 1] = {0};
    uint64_t triangles = 0;
    for (uint32_t i = 0; i < n; i++) {
        const sl_render_record *rec = &r->records[r->scratch_ids[i]];
        if (rec->index_count)
            at[rec->group + 1]++;
    }
    for (int g = 0; g < SL_RENDER_GROUPS; g++)
        at[g + 1] += at[g];
    uint32_t fill[SL_RENDER_GROUPS];
    memcpy(fill, at, sizeof fill);
    uint32_t drawn = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t id = r->scratch_ids[i];
        const sl_render_record *rec = &r->records[id];
        if (!rec->index_count)
            continue;
        if (pass != SL_RENDER_PASS_SHADED && rec->group >= SL_RENDER_GROUP_SEE_THROUGH)
            continue; /* see-through objects write no depth and no id: only their colour shows */
        sl_render_indirect *c = &r->cmds[fill[rec->group]++];
        c->count = rec->index_count;
        c->instance_count = 1;
        c->first_index = rec->first_index;
        c->base_vertex = rec->base_vertex;
        c->base_instance = id;
        triangles += rec->index_count / 3;
        drawn++;
    }
    if (drawn == 0)
        return SL_OK;
    glNamedBufferSubData(r->indirect_buffer, 0, (GLsizeiptr)(at[SL_RENDER_GROUPS] * sizeof(sl_render_indirect)), r->cmds);
    static const GLenum bufs[SL_RENDER_PASS_COUNT][2] = {
        {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1}, {GL_NONE, GL_COLOR_ATTACHMENT1}, {GL_NONE, GL_NONE}};
    glNamedFramebufferDrawBuffers(r->fbo, 2, bufs[pass]);
    glUseProgram(r->passes[pass].program);
    glBindVertexArray(r->vao);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, r->indirect_buffer);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SL_RENDER_OBJECT_BINDING, r->object_ssbo);
    if (pass == SL_RENDER_PASS_SHADED) {
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SL_RENDER_MATERIAL_BINDING, r->material_ssbo);
        glBindTextureUnit(0, r->texture_array);
    }
    glEnable(GL_DEPTH_TEST);
    for (int g = 0; g < SL_RENDER_GROUPS; g++) {
        uint32_t k = fill[g] - at[g];
        if (!k)
            continue;
        bool see = g >= SL_RENDER_GROUP_SEE_THROUGH;
        int facing = g % SL_RENDER_GROUP_SEE_THROUGH;
        if (facing == SL_RENDER_GROUP_TWO_SIDED)
            glDisable(GL_CULL_FACE);
        else {
            glEnable(GL_CULL_FACE);
            glCullFace(GL_BACK);
            glFrontFace(facing == SL_RENDER_GROUP_CULL_CCW ? GL_CCW : GL_CW);
        }
        if (see) {
            glDepthFunc(GL_GEQUAL); /* the oracle's see-through rule: seen where at least as near */
            glDepthMask(GL_FALSE);
            glEnablei(GL_BLEND, 0);
            glBlendFuncSeparatei(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
            glColorMaski(1, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE); /* no id */
        } else {
            glDepthFunc(r->depth_equal && pass != SL_RENDER_PASS_DEPTH ? GL_EQUAL : GL_GREATER);
            glDepthMask(r->depth_equal && pass != SL_RENDER_PASS_DEPTH ? GL_FALSE : GL_TRUE);
            glDisablei(GL_BLEND, 0);
        }
        glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, (const void *)(uintptr_t)(at[g] * sizeof(sl_render_indirect)),
                                    (GLsizei)k, 0);
        r->frame.draw_calls++;
    }
    glDisablei(GL_BLEND, 0);
    glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_GREATER);
    if (pass != SL_RENDER_PASS_DEPTH || !r->depth_equal) {
        r->frame.objects_drawn += drawn;
        r->frame.triangles_drawn += triangles;
    }
    return sl_render_check(r, "glMultiDrawElementsIndirect", err);
}

/* ---- draws and frames ---- */

static sl_render_pass pass_of(sl_render_kind kind)
{
    return kind == SL_RENDER_IDS ? SL_RENDER_PASS_IDS : kind == SL_RENDER_DEPTH ? SL_RENDER_PASS_DEPTH : SL_RENDER_PASS_SHADED;
}

/* Draw ids with the frame's pass (and the depth pre-pass when asked). */
static sl_status draw_set(sl_renderer r, const uint32_t *ids, uint32_t count, sl_render_pass pass, sl_error *err)
{
    sl_status st;
    if (r->opt.depth_prepass && pass != SL_RENDER_PASS_DEPTH) {
        r->depth_equal = true;
        st = sl_render_draw_ids(r, ids, count, SL_RENDER_PASS_DEPTH, err);
        if (st == SL_OK)
            st = sl_render_draw_ids(r, ids, count, pass, err);
        r->depth_equal = false;
        return st;
    }
    return sl_render_draw_ids(r, ids, count, pass, err);
}

static sl_status check_view(sl_renderer r, const sl_view *view, const char *what, sl_error *err)
{
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: renderer is NULL", what);
    sl_error verr;
    if (sl_view_validate(view, &verr) != SL_OK)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: %s", what, verr.message);
    return SL_OK;
}

static double timer_ms(sl_renderer r, GLuint q)
{
    GLuint64 ns = 0;
    glGetQueryObjectui64v(q, GL_QUERY_RESULT, &ns);
    return (double)ns * 1e-6;
}

static void stats_out(sl_renderer r, sl_render_frame_stats *stats)
{
    if (stats)
        *stats = r->frame;
}

sl_status sl_renderer_draw(sl_renderer r, const sl_view *view, const uint32_t *ids, uint32_t count, sl_render_kind kind,
                           sl_render_frame_stats *stats, sl_error *err)
{
    sl_status st = check_view(r, view, "sl_renderer_draw", err);
    if (st != SL_OK || (st = sl_render_enter(r, "sl_renderer_draw", err)) != SL_OK)
        return st;
    memset(&r->frame, 0, sizeof r->frame);
    r->frame.gpu_draw_ms = r->frame.gpu_query_ms = -1.0;
    sl_render_pass pass = pass_of(kind);
    double t0 = sl_render_now();
    sl_render_set_view(r, view);
    if ((st = sl_render_clear(r, pass, err)) != SL_OK)
        return st;
    if (r->timers_ok)
        glBeginQuery(GL_TIME_ELAPSED, r->timers[0]);
    st = draw_set(r, ids, count, pass, err);
    if (r->timers_ok)
        glEndQuery(GL_TIME_ELAPSED);
    if (st != SL_OK)
        return st;
    double t1 = sl_render_now();
    glFinish();
    double t2 = sl_render_now();
    r->frame.draw_ms = (t1 - t0) * 1e3;
    r->frame.finish_ms = (t2 - t1) * 1e3;
    r->frame.frame_ms = (t2 - t0) * 1e3;
    if (r->timers_ok)
        r->frame.gpu_draw_ms = timer_ms(r, r->timers[0]);
    if ((st = sl_render_check(r, "sl_renderer_draw: glFinish", err)) != SL_OK)
        return st;
    stats_out(r, stats);
    return SL_OK;
}

sl_status sl_renderer_frame(sl_renderer r, sl_culler culler, const sl_view *view, sl_render_kind kind, uint32_t *ids,
                            uint32_t *count, sl_render_frame_stats *stats, sl_error *err)
{
    sl_status st = check_view(r, view, "sl_renderer_frame", err);
    if (st != SL_OK || (st = sl_render_enter(r, "sl_renderer_frame", err)) != SL_OK)
        return st;
    memset(&r->frame, 0, sizeof r->frame);
    r->frame.gpu_draw_ms = r->frame.gpu_query_ms = -1.0;
    sl_render_pass pass = pass_of(kind);
    uint32_t *set = ids ? ids : r->frame_ids;
    uint32_t n = 0;
    double t0 = sl_render_now();
    sl_render_set_view(r, view);
    if ((st = sl_render_clear(r, pass, err)) != SL_OK)
        return st;
    r->in_frame = true;
    r->culler_drew = false;
    r->frame_pass = pass;
    double tc = sl_render_now();
    if (culler) {
        st = sl_culler_cull_view(culler, view, set, r->object_count, &n, err);
        if (st == SL_OK)
            st = sl_render_check(r, "sl_renderer_frame: the culler's draws", err);
    } else {
        for (uint32_t i = 0; i < r->object_count; i++)
            set[i] = i;
        n = r->object_count;
    }
    double t1 = sl_render_now();
    if (st == SL_OK && !r->culler_drew) {
        if (r->timers_ok)
            glBeginQuery(GL_TIME_ELAPSED, r->timers[0]);
        st = draw_set(r, set, n, pass, err);
        if (r->timers_ok)
            glEndQuery(GL_TIME_ELAPSED);
    }
    r->in_frame = false;
    if (st != SL_OK)
        return st;
    double t2 = sl_render_now();
    glFinish();
    double t3 = sl_render_now();
    r->frame.cull_ms = (t1 - tc) * 1e3;
    r->frame.draw_ms = (t2 - t1 + tc - t0) * 1e3;
    r->frame.finish_ms = (t3 - t2) * 1e3;
    r->frame.frame_ms = (t3 - t0) * 1e3;
    if (r->timers_ok && !r->culler_drew)
        r->frame.gpu_draw_ms = timer_ms(r, r->timers[0]);
    if (culler) {
        sl_culler_stats(culler, &r->frame.cull);
        if (r->frame.queries == 0)
            r->frame.queries = r->frame.cull.queries;
    }
    if ((st = sl_render_check(r, "sl_renderer_frame: glFinish", err)) != SL_OK)
        return st;
    if (count)
        *count = n;
    stats_out(r, stats);
    return SL_OK;
}

/* ---- read-back ---- */

static sl_status read_texture(sl_renderer r, GLuint tex, GLenum format, GLenum type, size_t pixel_bytes, void *out,
                              const char *what, sl_error *err)
{
    if (!r || !out)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: %s is NULL", what, r ? "the buffer" : "renderer");
    sl_status st = sl_render_enter(r, what, err);
    if (st != SL_OK)
        return st;
    size_t row = (size_t)r->width * pixel_bytes, bytes = row * r->height;
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glGetTextureImage(tex, 0, format, type, (GLsizei)bytes, out);
    if ((st = sl_render_check(r, what, err)) != SL_OK)
        return st;
    /* GL stores the bottom row first: flip to row 0 at the top */
    uint8_t *p = out, tmp[4096];
    for (uint32_t y = 0; y < r->height / 2; y++) {
        uint8_t *a = p + y * row, *b = p + (r->height - 1 - y) * row;
        for (size_t off = 0; off < row; off += sizeof tmp) {
            size_t k = row - off < sizeof tmp ? row - off : sizeof tmp;
            memcpy(tmp, a + off, k);
            memcpy(a + off, b + off, k);
            memcpy(b + off, tmp, k);
        }
    }
    return SL_OK;
}

sl_status sl_renderer_read_rgba(sl_renderer r, uint8_t *rgba, sl_error *err)
{
    return read_texture(r, r ? r->color_tex : 0, GL_RGBA, GL_UNSIGNED_BYTE, 4, rgba, "sl_renderer_read_rgba", err);
}

sl_status sl_renderer_read_ids(sl_renderer r, uint32_t *ids, sl_error *err)
{
    return read_texture(r, r ? r->id_tex : 0, GL_RED_INTEGER, GL_UNSIGNED_INT, 4, ids, "sl_renderer_read_ids", err);
}

sl_status sl_renderer_read_depth(sl_renderer r, float *depth, sl_error *err)
{
    return read_texture(r, r ? r->depth_tex : 0, GL_DEPTH_COMPONENT, GL_FLOAT, 4, depth, "sl_renderer_read_depth", err);
}

sl_status sl_renderer_write_png(sl_renderer r, const char *path, sl_error *err)
{
    if (!r || !path)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_write_png: %s is NULL", r ? "path" : "renderer");
    size_t bytes = (size_t)r->width * r->height * 4;
    uint8_t *px = sl_render_alloc(r, bytes);
    if (!px)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_renderer_write_png: %zu bytes", bytes);
    sl_status st = sl_renderer_read_rgba(r, px, err);
    if (st == SL_OK) {
        for (size_t i = 3; i < bytes; i += 4)
            px[i] = 255; /* an opaque image */
        st = sl_png_write(path, r->width, r->height, 4, px, 0, err);
    }
    sl_render_free(r, px, bytes);
    return st;
}

sl_status sl_renderer_present(sl_renderer r, uint32_t width, uint32_t height, sl_error *err)
{
    if (!r)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_renderer_present: renderer is NULL");
    sl_status st = sl_render_enter(r, "sl_renderer_present", err);
    if (st != SL_OK)
        return st;
    GLint target = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &target);
    if ((GLuint)target == r->fbo)
        target = 0;
    glNamedFramebufferReadBuffer(r->fbo, GL_COLOR_ATTACHMENT0);
    glBlitNamedFramebuffer(r->fbo, (GLuint)target, 0, 0, (GLint)r->width, (GLint)r->height, 0, 0, (GLint)width,
                           (GLint)height, GL_COLOR_BUFFER_BIT, GL_LINEAR);
    glBindFramebuffer(GL_FRAMEBUFFER, (GLuint)target);
    return sl_render_check(r, "sl_renderer_present: glBlitNamedFramebuffer", err);
}

/* gpu-hiz: two-pass GPU-driven culling against a depth pyramid (a method of the render layer,
 * created by sl_renderer_create_culler; docs/gpu-hiz.md).
 *
 * Per frame, on the renderer's framebuffer:
 *   1. select (compute): last frame's visible set, solid objects in the frustum, as indirect
 *      commands (flag D1);
 *   2. pass 1: draw them (the frame's pass: shaded, ids or depth), one multi-draw per facing group;
 *   3. pyramid (compute): level 0 is the depth texture itself, each next level (in an SSBO) the
 *      farthest (smallest: reversed z) of 2x2 texels of the one below, down to 1x1 (sizes halved
 *      rounding up, so texel (x, y) of level k covers pixels [x 2^k, (x + 1) 2^k) of the image);
 *   4. test (compute): every object's box, grown by the float rounding of its coordinates, is
 *      projected: outside the frustum culled; a corner behind the near plane: visible; else the
 *      pixels whose centres its screen rectangle (grown by `margin` pixels) holds, and its nearest
 *      depth (the largest corner depth; depth is monotone in eye distance, which is linear, so a
 *      corner bounds the box) compared with the farthest pyramid depth over those pixels (the
 *      coarsest level where they span at most 2x2 texels): visible when at least as near
 *      (flag VIS, next frame's visible set); the visible ones not drawn in pass 1 are commands
 *      for pass 2 (flag D2), see-through objects always there (they never block, so they are not
 *      in pass 1 and are drawn after the solid ones);
 *   5. pass 2: draw them;
 *   6. read back the flags: the ids drawn (D1 or D2), ascending.
 * Commands are appended with atomic counters and drawn with glMultiDrawElementsIndirectCount when
 * the context has it (GL 4.6 or ARB_indirect_parameters; option indirect_count), else every
 * object has a fixed command whose instance count is 0 or 1 (glMultiDrawElementsIndirect).
 *
 * Guarantee: SL_CONSERVATIVE_AT_RESOLUTION. Pass 1's depth holds only objects drawn in this frame,
 * so at every pixel it is never nearer than the frame's final depth. An object that shows at
 * pixel p shows a fragment there at least as near as the final depth, hence as pass 1's; that
 * fragment lies on a triangle whose vertices are inside the object's box, and GL interpolates depth
 * between the vertices' depths, so it is no nearer than the box's nearest corner; p is in the
 * box's pixel rectangle (its centre is covered by the object's projection, inside the box's); and
 * the pyramid texel over p holds a depth no nearer than pass 1's at p. So the test passes and the
 * object is drawn (in pass 1 already, or in pass 2). The one-frame lag (pass 1 draws last frame's
 * set) only costs speed: an object that became visible is found by the test in the same frame.
 * Float rounding: the box is grown by 4e-7 of its coordinates' magnitude (the vertices' transform
 * in float), the rectangle by `margin` pixels (GL's vertex snapping: 1/256 pixel at 8 subpixel
 * bits, llvmpipe's), the depth comparison loosened by a relative 1e-5.
 * Objects hidden at this resolution may show at another, hence not SL_CONSERVATIVE. */
#include "render/backend_gl.h"

#include <math.h>
#include <string.h>

typedef struct hiz_config {
    bool indirect_count;
    float margin;
} hiz_config;

enum { FLAG_VIS = 1u, FLAG_D1 = 2u, FLAG_D2 = 4u };

/* std430 record of an object in the cull shader (7 uints) */
typedef struct hiz_record {
    uint32_t count, instance_count, first_index;
    int32_t base_vertex;
    uint32_t base_instance;
    uint32_t group, slot;
} hiz_record;

typedef struct hiz_state {
    sl_allocator alloc;
    sl_renderer r;
    uint32_t n;
    hiz_config cfg;
    PFNGLMULTIDRAWELEMENTSINDIRECTCOUNTPROC draw_count; /* NULL: zeroed instance counts */
    GLuint p_copy, p_reduce, p_cull;
    GLint u_copy_size, u_copy_dst_size, u_copy_dst_off, u_src_size, u_dst_size, u_src_off, u_dst_off;
    GLint u_vp, u_size, u_objects, u_mode, u_compact, u_margin, u_base;
    GLuint sampler;
    GLuint boxes, records, flags, pyramid;
    GLuint cmds[2], counts[2];          /* [0] pass 1, [1] pass 2 */
    uint32_t pyr_w, pyr_h, pyr_levels;
    uint32_t pyr_off[32], pyr_lw[32], pyr_lh[32];
    uint32_t group_base[SL_RENDER_GROUPS], group_size[SL_RENDER_GROUPS];
    uint32_t *host;                     /* [n] flags read back, then scratch */
    hiz_record *recs;                   /* [n] */
    float *box_data;                    /* [8 n] */
} hiz_state;

static const char g_help[] =
    "indirect_count=BOOL (default true): draw with glMultiDrawElementsIndirectCount when the context has it "
    "(GL 4.6 or ARB_indirect_parameters); false: one command per object, instance count 0 or 1\n"
    "margin=0.0625..4 (default 0.0625): pixels each box's screen rectangle grows by (vertex snapping)\n";

#define HIZ_SUMMARY                                                                                                   \
    "two-pass GPU-driven culling (GL only, sl_renderer_create_culler): last frame's visible set drawn, a depth "     \
    "pyramid and every object's box tested against it in compute shaders, the newly visible drawn with indirect "  \
    "count"

/* ---- shaders ---- */

static const char cs_copy[] = /* level 1 straight from the depth texture (level 0 is the texture) */
    "#version 450 core\n"
    "layout(local_size_x = 8, local_size_y = 8) in;\n"
    "layout(binding = 0) uniform sampler2D depth_tex;\n"
    "layout(std430, binding = 3) writeonly buffer Pyramid { float pyr[]; };\n"
    "uniform ivec2 size, dst_size;\n"
    "uniform int dst_off;\n"
    "void main() {\n"
    "    ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
    "    if (p.x >= dst_size.x || p.y >= dst_size.y) return;\n"
    "    ivec2 q = 2 * p;\n"
    "    bool rx = q.x + 1 < size.x, ry = q.y + 1 < size.y;\n"
    "    float m = texelFetch(depth_tex, q, 0).r;\n"
    "    if (rx) m = min(m, texelFetch(depth_tex, q + ivec2(1, 0), 0).r);\n"
    "    if (ry) m = min(m, texelFetch(depth_tex, q + ivec2(0, 1), 0).r);\n"
    "    if (rx && ry) m = min(m, texelFetch(depth_tex, q + ivec2(1, 1), 0).r);\n"
    "    pyr[dst_off + p.y * dst_size.x + p.x] = m;\n"
    "}\n";

static const char cs_reduce[] =
    "#version 450 core\n"
    "layout(local_size_x = 8, local_size_y = 8) in;\n"
    "layout(std430, binding = 3) buffer Pyramid { float pyr[]; };\n"
    "uniform ivec2 src_size, dst_size;\n"
    "uniform int src_off, dst_off;\n"
    "void main() {\n"
    "    ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
    "    if (p.x >= dst_size.x || p.y >= dst_size.y) return;\n"
    "    ivec2 q = 2 * p;\n"
    "    bool rx = q.x + 1 < src_size.x, ry = q.y + 1 < src_size.y;\n"
    "    float m = pyr[src_off + q.y * src_size.x + q.x];\n"
    "    if (rx) m = min(m, pyr[src_off + q.y * src_size.x + q.x + 1]);\n"
    "    if (ry) m = min(m, pyr[src_off + (q.y + 1) * src_size.x + q.x]);\n"
    "    if (rx && ry) m = min(m, pyr[src_off + (q.y + 1) * src_size.x + q.x + 1]);\n"
    "    pyr[dst_off + p.y * dst_size.x + p.x] = m;\n"
    "}\n";

static const char cs_cull[] =
    "#version 450 core\n"
    "layout(local_size_x = 64) in;\n"
    "struct Cmd { uint count, instance_count, first_index; int base_vertex; uint base_instance; };\n"
    "struct Rec { uint count, instance_count, first_index; int base_vertex; uint base_instance; uint group, slot; };\n"
    "layout(binding = 0) uniform sampler2D depth_tex;\n" /* the pyramid's level 0 */
    "layout(std430, binding = 3) readonly buffer Pyramid { float pyr[]; };\n" /* levels 1.. */
    "layout(std430, binding = 4) readonly buffer Boxes { vec4 box[]; };\n"
    "layout(std430, binding = 5) readonly buffer Records { Rec rec[]; };\n"
    "layout(std430, binding = 6) buffer Flags { uint flag[]; };\n"
    "layout(std430, binding = 7) writeonly buffer Out { Cmd cmd[]; };\n"
    "layout(std430, binding = 8) buffer Counts { uint n_cmd[]; };\n"
    "uniform mat4 vp;\n"          /* the renderer's: depth z'/w reversed, 1 near, 0 far */
    "uniform ivec2 size;\n"
    "uniform uint objects;\n"
    "uniform int mode;\n"         /* 0: select last frame's visible set; 1: the test */
    "uniform bool compact;\n"     /* append (indirect count) or one command per object */
    "uniform float margin;\n"
    "uniform uint base[6];\n"     /* first command of each group */
    "const uint VIS = 1u, D1 = 2u, D2 = 4u;\n"
    /* 0: outside the frustum or covers no pixel centre; 1: rect and dnear set; 2: crosses the near plane */
    "int project(uint i, out ivec4 rect, out float dnear) {\n"
    "    vec3 lo = box[2u * i].xyz, hi = box[2u * i + 1u].xyz;\n"
    "    uint all_out = 63u;\n"
    "    bool cross_near = false;\n"
    "    vec2 mn = vec2(1e30), mx = vec2(-1e30);\n"
    "    dnear = 0.0;\n"
    "    rect = ivec4(0);\n"
    "    for (int k = 0; k < 8; k++) {\n"
    "        vec3 p = vec3((k & 1) != 0 ? hi.x : lo.x, (k & 2) != 0 ? hi.y : lo.y, (k & 4) != 0 ? hi.z : lo.z);\n"
    "        vec4 c = vp * vec4(p, 1.0);\n"
    "        uint m = 0u;\n"
    "        if (c.x < -c.w) m |= 1u;\n"
    "        if (c.x > c.w) m |= 2u;\n"
    "        if (c.y < -c.w) m |= 4u;\n"
    "        if (c.y > c.w) m |= 8u;\n"
    "        if (c.z < 0.0) m |= 16u;\n"
    "        if (c.z > c.w) m |= 32u;\n"
    "        all_out &= m;\n"
    "        if (!(c.w > 0.0) || c.z > c.w) { cross_near = true; continue; }\n"
    "        vec2 w = (c.xy / c.w * 0.5 + 0.5) * vec2(size);\n"
    "        mn = min(mn, w);\n"
    "        mx = max(mx, w);\n"
    "        dnear = max(dnear, c.z / c.w);\n"
    "    }\n"
    "    if (all_out != 0u) return 0;\n"
    "    if (cross_near) return 2;\n"
    /* pixel i's centre is i + 0.5: the centres in [mn - margin, mx + margin] */
    "    rect = ivec4(ivec2(ceil(mn - margin - 0.5)), ivec2(floor(mx + margin - 0.5)));\n"
    "    rect = ivec4(max(rect.xy, ivec2(0)), min(rect.zw, size - 1));\n"
    "    return rect.x <= rect.z && rect.y <= rect.w ? 1 : 0;\n"
    "}\n"
    "bool pyramid_passes(ivec4 r, float dnear) {\n"
    "    int k = 0, off = 0;\n"
    "    ivec2 sz = size;\n"
    "    while ((r.z >> k) - (r.x >> k) > 1 || (r.w >> k) - (r.y >> k) > 1) {\n"
    "        off += sz.x * sz.y;\n"
    "        sz = (sz + 1) / 2;\n"
    "        k++;\n"
    "    }\n"
    "    float far_d = 1.0;\n"
    "    for (int y = r.y >> k; y <= (r.w >> k); y++)\n"
    "        for (int x = r.x >> k; x <= (r.z >> k); x++)\n"
    "            far_d = min(far_d, k == 0 ? texelFetch(depth_tex, ivec2(x, y), 0).r : pyr[off + y * sz.x + x]);\n"
    "    return dnear * (1.0 + 1e-5) >= far_d;\n"
    "}\n"
    "void emit(uint i, bool on) {\n"
    "    Rec r = rec[i];\n"
    "    Cmd c = Cmd(r.count, on ? 1u : 0u, r.first_index, r.base_vertex, r.base_instance);\n"
    "    if (!compact) cmd[base[r.group] + r.slot] = c;\n"
    "    else if (on) cmd[base[r.group] + atomicAdd(n_cmd[r.group], 1u)] = c;\n"
    "}\n"
    "void main() {\n"
    "    uint i = gl_GlobalInvocationID.x;\n"
    "    if (i >= objects) return;\n"
    "    ivec4 r;\n"
    "    float dn;\n"
    "    int f = project(i, r, dn);\n"
    "    uint fl = flag[i];\n"
    "    bool solid = rec[i].group < 3u;\n"
    "    if (mode == 0) {\n"
    "        bool on = solid && (fl & VIS) != 0u && f != 0;\n"
    "        emit(i, on);\n"
    "        flag[i] = on ? D1 : 0u;\n"
    "        return;\n"
    "    }\n"
    "    bool v = f == 2 || (f == 1 && pyramid_passes(r, dn));\n"
    "    bool d2 = v && (fl & D1) == 0u;\n"
    "    emit(i, d2);\n"
    "    flag[i] = fl | (v ? VIS : 0u) | (d2 ? D2 : 0u);\n"
    "}\n";

#define PYR_BINDING 3
#define BOX_BINDING 4
#define REC_BINDING 5
#define FLAG_BINDING 6
#define CMD_BINDING 7
#define COUNT_BINDING 8

/* ---- set-up ---- */

static sl_status compute_program(sl_renderer r, const char *name, const char *src, GLuint *out, sl_error *err)
{
    GLuint s = glCreateShader(GL_COMPUTE_SHADER);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    char log[300] = "";
    if (!ok) {
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        glDeleteShader(s);
        r->debug_pending = false;
        return sl_render_fail(err, SL_ERROR_INTERNAL, "gpu-hiz: the %s compute shader does not compile: %s", name, log);
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, s);
    glLinkProgram(p);
    glDeleteShader(s);
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        glDeleteProgram(p);
        return sl_render_fail(err, SL_ERROR_INTERNAL, "gpu-hiz: the %s compute program does not link: %s", name, log);
    }
    *out = p;
    return SL_OK;
}

/* The boxes (grown by the float rounding of their coordinates) and the draw records, grouped as
 * the renderer groups them. */
static sl_status upload_objects(hiz_state *s, sl_error *err)
{
    sl_renderer r = s->r;
    const sl_aabb *b = sl_scene_object_bounds_array(r->scene);
    for (uint32_t i = 0; i < s->n; i++) {
        double ext = fmax(fmax(fmax(fabs(b[i].min.x), fabs(b[i].max.x)), fmax(fabs(b[i].min.y), fabs(b[i].max.y))),
                          fmax(fabs(b[i].min.z), fabs(b[i].max.z)));
        float m = (float)(4e-7 * (ext + 1.0));
        float *o = s->box_data + 8 * i;
        o[0] = b[i].min.x - m, o[1] = b[i].min.y - m, o[2] = b[i].min.z - m, o[3] = 1.0f;
        o[4] = b[i].max.x + m, o[5] = b[i].max.y + m, o[6] = b[i].max.z + m, o[7] = 1.0f;
    }
    memset(s->group_size, 0, sizeof s->group_size);
    for (uint32_t i = 0; i < s->n; i++) {
        const sl_render_record *rec = &r->records[i];
        hiz_record *h = &s->recs[i];
        h->count = rec->index_count;
        h->instance_count = 1;
        h->first_index = rec->first_index;
        h->base_vertex = rec->base_vertex;
        h->base_instance = i;
        h->group = rec->group;
        h->slot = s->group_size[rec->group]++;
    }
    uint32_t at = 0;
    for (int g = 0; g < SL_RENDER_GROUPS; g++) {
        s->group_base[g] = at;
        at += s->group_size[g];
    }
    glNamedBufferSubData(s->boxes, 0, (GLsizeiptr)s->n * 32, s->box_data);
    glNamedBufferSubData(s->records, 0, (GLsizeiptr)s->n * (GLsizeiptr)sizeof(hiz_record), s->recs);
    return sl_render_check(r, "gpu-hiz: uploading boxes and records", err);
}

static void hiz_destroy(void *state)
{
    hiz_state *s = state;
    if (!s)
        return;
    sl_renderer r = s->r;
    if (sl_render_enter(r, "gpu-hiz: destroy", NULL) == SL_OK) {
        GLuint progs[3] = {s->p_copy, s->p_reduce, s->p_cull};
        for (int i = 0; i < 3; i++)
            if (progs[i])
                glDeleteProgram(progs[i]);
        GLuint bufs[8] = {s->boxes, s->records, s->flags, s->pyramid, s->cmds[0], s->cmds[1], s->counts[0], s->counts[1]};
        glDeleteBuffers(8, bufs);
        if (s->sampler)
            glDeleteSamplers(1, &s->sampler);
        sl_render_check(r, "gpu-hiz: destroy", NULL);
    }
    size_t n = s->n ? s->n : 1;
    sl_allocator a = s->alloc;
    if (s->host)
        a.free(a.user, s->host, n * 4);
    if (s->recs)
        a.free(a.user, s->recs, n * sizeof *s->recs);
    if (s->box_data)
        a.free(a.user, s->box_data, n * 32);
    a.free(a.user, s, sizeof *s);
}

static bool has_extension(const char *name)
{
    GLint n = 0;
    glGetIntegerv(GL_NUM_EXTENSIONS, &n);
    for (GLint i = 0; i < n; i++) {
        const char *e = (const char *)glGetStringi(GL_EXTENSIONS, (GLuint)i);
        if (e && strcmp(e, name) == 0)
            return true;
    }
    return false;
}

static sl_status hiz_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    hiz_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_opts_bool(o, "indirect_count", true, &c->indirect_count, err)) != SL_OK ||
        (st = sl_opts_float(o, "margin", 0.0625f, 0.0625f, 4.0f, &c->margin, err)) != SL_OK)
        return st;
    return SL_OK;
}

static sl_status hiz_create(sl_scene scene, const void *config, const sl_cull_extras *extras, const sl_allocator *alloc,
                            void **state, sl_error *err)
{
    sl_renderer r;
    if (!extras || !sl_render_backend_of(extras->backend, &r))
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT,
                              "gpu-hiz: draws with a renderer's GL backend only (sl_renderer_create_culler)");
    if (r->scene != scene)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "gpu-hiz: the renderer draws another scene");
    sl_status st = sl_render_enter(r, "gpu-hiz: create", err);
    if (st != SL_OK)
        return st;
    hiz_state *s = alloc->alloc(alloc->user, sizeof *s, 16);
    if (!s)
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "gpu-hiz: out of memory");
    memset(s, 0, sizeof *s);
    s->alloc = *alloc;
    s->r = r;
    s->n = r->object_count;
    s->cfg = *(const hiz_config *)config;
    size_t n = s->n ? s->n : 1;
    s->host = alloc->alloc(alloc->user, n * 4, 16);
    s->recs = alloc->alloc(alloc->user, n * sizeof *s->recs, 16);
    s->box_data = alloc->alloc(alloc->user, n * 32, 16);
    if (!s->host || !s->recs || !s->box_data) {
        hiz_destroy(s);
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "gpu-hiz: out of memory for %u objects", s->n);
    }
    if (s->cfg.indirect_count) {
        GLint major = 0, minor = 0;
        glGetIntegerv(GL_MAJOR_VERSION, &major);
        glGetIntegerv(GL_MINOR_VERSION, &minor);
        if (major * 10 + minor >= 46)
            s->draw_count = (PFNGLMULTIDRAWELEMENTSINDIRECTCOUNTPROC)eglGetProcAddress("glMultiDrawElementsIndirectCount");
        else if (has_extension("GL_ARB_indirect_parameters"))
            s->draw_count =
                (PFNGLMULTIDRAWELEMENTSINDIRECTCOUNTPROC)eglGetProcAddress("glMultiDrawElementsIndirectCountARB");
    }
    if ((st = compute_program(r, "pyramid copy", cs_copy, &s->p_copy, err)) != SL_OK ||
        (st = compute_program(r, "pyramid reduce", cs_reduce, &s->p_reduce, err)) != SL_OK ||
        (st = compute_program(r, "box test", cs_cull, &s->p_cull, err)) != SL_OK) {
        hiz_destroy(s);
        return st;
    }
    s->u_copy_size = glGetUniformLocation(s->p_copy, "size");
    s->u_copy_dst_size = glGetUniformLocation(s->p_copy, "dst_size");
    s->u_copy_dst_off = glGetUniformLocation(s->p_copy, "dst_off");
    s->u_src_size = glGetUniformLocation(s->p_reduce, "src_size");
    s->u_dst_size = glGetUniformLocation(s->p_reduce, "dst_size");
    s->u_src_off = glGetUniformLocation(s->p_reduce, "src_off");
    s->u_dst_off = glGetUniformLocation(s->p_reduce, "dst_off");
    s->u_vp = glGetUniformLocation(s->p_cull, "vp");
    s->u_size = glGetUniformLocation(s->p_cull, "size");
    s->u_objects = glGetUniformLocation(s->p_cull, "objects");
    s->u_mode = glGetUniformLocation(s->p_cull, "mode");
    s->u_compact = glGetUniformLocation(s->p_cull, "compact");
    s->u_margin = glGetUniformLocation(s->p_cull, "margin");
    s->u_base = glGetUniformLocation(s->p_cull, "base");
    glCreateSamplers(1, &s->sampler);
    glSamplerParameteri(s->sampler, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glSamplerParameteri(s->sampler, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glSamplerParameteri(s->sampler, GL_TEXTURE_COMPARE_MODE, GL_NONE);
    GLuint bufs[7];
    glCreateBuffers(7, bufs);
    s->boxes = bufs[0], s->records = bufs[1], s->flags = bufs[2];
    s->cmds[0] = bufs[3], s->cmds[1] = bufs[4], s->counts[0] = bufs[5], s->counts[1] = bufs[6];
    glNamedBufferStorage(s->boxes, (GLsizeiptr)n * 32, NULL, GL_DYNAMIC_STORAGE_BIT);
    glNamedBufferStorage(s->records, (GLsizeiptr)(n * sizeof(hiz_record)), NULL, GL_DYNAMIC_STORAGE_BIT);
    glNamedBufferStorage(s->flags, (GLsizeiptr)n * 4, NULL, GL_DYNAMIC_STORAGE_BIT);
    for (int k = 0; k < 2; k++) {
        glNamedBufferStorage(s->cmds[k], (GLsizeiptr)(n * sizeof(sl_render_indirect)), NULL, 0);
        glNamedBufferStorage(s->counts[k], SL_RENDER_GROUPS * 4, NULL, GL_DYNAMIC_STORAGE_BIT);
    }
    const uint32_t zero = 0;
    glClearNamedBufferData(s->flags, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero); /* nothing visible yet */
    if ((st = sl_render_check(r, "gpu-hiz: making buffers", err)) != SL_OK || (st = upload_objects(s, err)) != SL_OK) {
        hiz_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status hiz_scene_changed(void *state, sl_error *err)
{
    hiz_state *s = state;
    sl_status st = sl_render_enter(s->r, "gpu-hiz: scene_changed", err);
    return st == SL_OK ? upload_objects(s, err) : st;
}

/* The pyramid's levels for the framebuffer's size (the buffer remade when it changes). */
static sl_status need_pyramid(hiz_state *s, sl_error *err)
{
    sl_renderer r = s->r;
    if (s->pyramid && s->pyr_w == r->width && s->pyr_h == r->height)
        return SL_OK;
    uint32_t w = r->width, h = r->height, total = 0, k = 0;
    for (;;) {
        s->pyr_off[k] = total;
        s->pyr_lw[k] = w;
        s->pyr_lh[k] = h;
        total += w * h;
        k++;
        if (w == 1 && h == 1)
            break;
        w = (w + 1) / 2;
        h = (h + 1) / 2;
    }
    s->pyr_levels = k;
    if (s->pyramid)
        glDeleteBuffers(1, &s->pyramid);
    glCreateBuffers(1, &s->pyramid);
    glNamedBufferStorage(s->pyramid, (GLsizeiptr)total * 4, NULL, 0);
    s->pyr_w = r->width;
    s->pyr_h = r->height;
    return sl_render_check(r, "gpu-hiz: the pyramid's buffer", err);
}

/* Set one facing group's state for a pass (the renderer's rules, render_internal.h). */
static void group_state(int g, sl_render_pass pass)
{
    sl_render_facing_state(g % SL_RENDER_GROUP_SEE_THROUGH);
    if (g >= SL_RENDER_GROUP_SEE_THROUGH) { /* shaded pass only: seen where at least as near, no depth, no id */
        (void)pass;
        glDepthFunc(GL_GEQUAL);
        glDepthMask(GL_FALSE);
        glEnablei(GL_BLEND, 0);
        glBlendFuncSeparatei(0, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
        glColorMaski(1, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    } else {
        glDepthFunc(GL_GREATER);
        glDepthMask(GL_TRUE);
        glDisablei(GL_BLEND, 0);
        glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    }
}

/* Draw command list k (0: pass 1, solid groups only; 1: pass 2, every group). */
static sl_status draw_list(hiz_state *s, int k, sl_render_pass pass, sl_error *err)
{
    sl_renderer r = s->r;
    static const GLenum bufs[SL_RENDER_PASS_COUNT][2] = {
        {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1}, {GL_NONE, GL_COLOR_ATTACHMENT1}, {GL_NONE, GL_NONE}};
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glNamedFramebufferDrawBuffers(r->fbo, 2, bufs[pass]);
    glUseProgram(r->passes[pass].program);
    glBindVertexArray(r->vao);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SL_RENDER_OBJECT_BINDING, r->object_ssbo);
    if (pass == SL_RENDER_PASS_SHADED) { /* materials and textures, as sl_render_draw_ids binds them */
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SL_RENDER_MATERIAL_BINDING, r->material_ssbo);
        glBindTextureUnit(0, r->texture_array);
    }
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, s->cmds[k]);
    /* bound only for the count draws: Mesa 22.3's llvmpipe takes the draw count from a bound
     * parameter buffer in a plain glMultiDrawElementsIndirect too (drawing nothing here) */
    glBindBuffer(GL_PARAMETER_BUFFER, s->draw_count ? s->counts[k] : 0);
    glEnable(GL_DEPTH_TEST);
    int groups = k == 0 ? SL_RENDER_GROUP_SEE_THROUGH : SL_RENDER_GROUPS;
    for (int g = 0; g < groups; g++) {
        if (!s->group_size[g])
            continue;
        if (pass != SL_RENDER_PASS_SHADED && g >= SL_RENDER_GROUP_SEE_THROUGH)
            continue; /* see-through objects write no depth and no id: only their colour shows */
        group_state(g, pass);
        const void *first = (const void *)(uintptr_t)(s->group_base[g] * sizeof(sl_render_indirect));
        if (s->draw_count)
            s->draw_count(GL_TRIANGLES, GL_UNSIGNED_INT, first, (GLintptr)g * 4, (GLsizei)s->group_size[g],
                          (GLsizei)sizeof(sl_render_indirect));
        else
            glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, first, (GLsizei)s->group_size[g],
                                        (GLsizei)sizeof(sl_render_indirect));
        r->frame.draw_calls++;
    }
    glDisablei(GL_BLEND, 0);
    glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_GREATER);
    glBindBuffer(GL_PARAMETER_BUFFER, 0);
    return sl_render_check(r, k == 0 ? "gpu-hiz: pass 1 (indirect draws)" : "gpu-hiz: pass 2 (indirect draws)", err);
}

static void dispatch_cull(hiz_state *s, int mode)
{
    const uint32_t zero = 0;
    glClearNamedBufferData(s->counts[mode], GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    glUseProgram(s->p_cull);
    glUniformMatrix4fv(s->u_vp, 1, GL_FALSE, s->r->view_proj);
    glUniform2i(s->u_size, (GLint)s->r->width, (GLint)s->r->height);
    glUniform1ui(s->u_objects, s->n);
    glUniform1i(s->u_mode, mode);
    glUniform1i(s->u_compact, s->draw_count != NULL);
    glUniform1f(s->u_margin, s->cfg.margin);
    glUniform1uiv(s->u_base, SL_RENDER_GROUPS, s->group_base);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, PYR_BINDING, s->pyramid);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, BOX_BINDING, s->boxes);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, REC_BINDING, s->records);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, FLAG_BINDING, s->flags);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, CMD_BINDING, s->cmds[mode]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, COUNT_BINDING, s->counts[mode]);
    glDispatchCompute((s->n + 63) / 64, 1, 1);
    glMemoryBarrier(GL_COMMAND_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
}

static void build_pyramid(hiz_state *s)
{
    sl_renderer r = s->r;
    glBindTextureUnit(0, r->depth_tex);
    glBindSampler(0, s->sampler);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, PYR_BINDING, s->pyramid);
    if (s->pyr_levels > 1) {
        glUseProgram(s->p_copy);
        glUniform2i(s->u_copy_size, (GLint)r->width, (GLint)r->height);
        glUniform2i(s->u_copy_dst_size, (GLint)s->pyr_lw[1], (GLint)s->pyr_lh[1]);
        glUniform1i(s->u_copy_dst_off, (GLint)s->pyr_off[1]);
        glDispatchCompute((s->pyr_lw[1] + 7) / 8, (s->pyr_lh[1] + 7) / 8, 1);
    }
    glUseProgram(s->p_reduce);
    for (uint32_t k = 1; k + 1 < s->pyr_levels; k++) {
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
        glUniform2i(s->u_src_size, (GLint)s->pyr_lw[k], (GLint)s->pyr_lh[k]);
        glUniform2i(s->u_dst_size, (GLint)s->pyr_lw[k + 1], (GLint)s->pyr_lh[k + 1]);
        glUniform1i(s->u_src_off, (GLint)s->pyr_off[k]);
        glUniform1i(s->u_dst_off, (GLint)s->pyr_off[k + 1]);
        glDispatchCompute((s->pyr_lw[k + 1] + 7) / 8, (s->pyr_lh[k + 1] + 7) / 8, 1);
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
}

static sl_status hiz_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    hiz_state *s = state;
    sl_renderer r = s->r;
    sl_status st = sl_render_enter(r, "gpu-hiz", err);
    if (st != SL_OK)
        return st;
    if (view->width != r->width || view->height != r->height)
        return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT,
                              "gpu-hiz: the view is %ux%u but the renderer's framebuffer is %ux%u (sl_renderer_resize)",
                              view->width, view->height, r->width, r->height);
    if ((st = need_pyramid(s, err)) != SL_OK)
        return st;
    double t0 = sl_render_now();
    sl_render_set_view(r, view);
    sl_render_pass pass = SL_RENDER_PASS_SHADED;
    if (r->in_frame) {
        r->culler_drew = true; /* the frame cleared; these draws are the frame */
        pass = r->frame_pass;
    } else {
        memset(&r->frame, 0, sizeof r->frame);
        r->frame.gpu_draw_ms = r->frame.gpu_query_ms = -1.0;
        if ((st = sl_render_clear(r, SL_RENDER_PASS_SHADED, err)) != SL_OK)
            return st;
    }
    dispatch_cull(s, 0);
    if ((st = draw_list(s, 0, pass, err)) != SL_OK)
        return st;
    double t1 = sl_render_now();
    build_pyramid(s);
    dispatch_cull(s, 1); /* reads level 0 from the depth texture bound by build_pyramid */
    glBindSampler(0, 0);
    glBindTextureUnit(0, 0);
    if ((st = sl_render_check(r, "gpu-hiz: pyramid and box test (compute)", err)) != SL_OK)
        return st;
    double t2 = sl_render_now();
    if ((st = draw_list(s, 1, pass, err)) != SL_OK)
        return st;
    double t3 = sl_render_now();
    glGetNamedBufferSubData(s->flags, 0, (GLsizeiptr)s->n * 4, s->host);
    if ((st = sl_render_check(r, "gpu-hiz: reading the flags back", err)) != SL_OK)
        return st;
    double t4 = sl_render_now();
    uint32_t k = 0, drawn = 0;
    uint64_t triangles = 0;
    for (uint32_t i = 0; i < s->n; i++)
        if (s->host[i] & (FLAG_D1 | FLAG_D2)) {
            out[k++] = i;
            if (pass == SL_RENDER_PASS_SHADED || r->records[i].group < SL_RENDER_GROUP_SEE_THROUGH) {
                drawn++;
                triangles += r->records[i].index_count / 3;
            }
        }
    *count = k;
    r->frame.objects_drawn += drawn;
    r->frame.triangles_drawn += triangles;
    r->frame.wait_ms += (t4 - t3) * 1e3; /* the read-back waits for the GPU's frame */
    stats->objects_tested = s->n;
    stats->occlusion_tests = s->n;
    sl_cull_phase(stats, "select+pass1", (t1 - t0) * 1e3);
    sl_cull_phase(stats, "pyramid+test", (t2 - t1) * 1e3);
    sl_cull_phase(stats, "pass2", (t3 - t2) * 1e3);
    sl_cull_phase(stats, "readback", (t4 - t3) * 1e3);
    return SL_OK;
}

#define HIZ_SUITS "the GL renderer: GPU-driven culling of any scene (last frame's set drawn, the rest tested on the GPU)"
const sl_cull_method sl_render_method_gpu_hiz = {
    .name = "gpu-hiz",
    .suits = HIZ_SUITS,
    .summary = HIZ_SUMMARY,
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE_AT_RESOLUTION,
    .config_size = sizeof(hiz_config),
    .depth = SL_DEPTH_CLIP_Z,
    .configure = hiz_configure,
    .create_with = hiz_create,
    .draws = true,
    .cull = hiz_cull,
    .scene_changed = hiz_scene_changed,
    .destroy = hiz_destroy,
};

const sl_cull_method_desc sl_render_desc_gpu_hiz = {"gpu-hiz", HIZ_SUMMARY, g_help, SL_CONSERVATIVE_AT_RESOLUTION,
                                                    false, HIZ_SUITS};

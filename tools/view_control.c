/* `sightline view` without a window: the methods to cycle through, the walk/fly controller, the
 * HUD's text (tools/view.h). */
#include "view.h"

#include "tool.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEG ((float)(M_PI / 180.0))
#define MIN_EYE 0.3f

/* ---- methods ---- */

static bool known_method(const char *name, bool (*is_render_method)(const char *), sl_error *err)
{
    uint32_t index;
    if (!strcmp(name, VIEW_NO_CULLING) || (is_render_method && is_render_method(name)))
        return true;
    return sl_cull_method_find(name, &index, err) == SL_OK;
}

static view_method *find(view_methods *ms, const char *name, size_t len)
{
    for (uint32_t i = 0; i < ms->count; i++)
        if (strlen(ms->m[i].name) == len && !strncmp(ms->m[i].name, name, len))
            return &ms->m[i];
    return NULL;
}

/* Append "text" (len bytes, commas kept) to m's options. */
static sl_status append_options(view_method *m, const char *text, size_t len, sl_error *err)
{
    size_t have = strlen(m->options);
    if (have + (have ? 1 : 0) + len + 1 > sizeof m->options)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "options of method '%s' are too long", m->name);
    if (have)
        m->options[have++] = ',';
    memcpy(m->options + have, text, len);
    m->options[have + len] = '\0';
    return SL_OK;
}

sl_status view_methods_parse(const char *text, bool (*is_render_method)(const char *name), view_methods *out,
                             sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (!text)
        text = VIEW_NO_CULLING ",vfc";
    const char *p = text;
    for (;;) {
        size_t len = strcspn(p, ",");
        size_t name_len = strcspn(p, ":,");
        if (!name_len)
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: empty method name in '%s'", text);
        if (name_len >= sizeof out->m[0].name)
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: method name '%.*s' is too long", (int)name_len,
                             p);
        if (out->count == VIEW_MAX_METHODS)
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: at most %d methods", VIEW_MAX_METHODS);
        view_method *m = &out->m[out->count];
        memcpy(m->name, p, name_len);
        m->name[name_len] = '\0';
        if (find(out, m->name, name_len))
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: '%s' is listed twice", m->name);
        sl_error local;
        if (!known_method(m->name, is_render_method, &local))
            return tool_fail(err, SL_ERROR_NOT_FOUND, "--methods: %s", local.message);
        /* NAME:k=v:k=v -> options "k=v,k=v" */
        for (size_t i = name_len; i < len;) {
            size_t j = i + 1, n = 0;
            while (j + n < len && p[j + n] != ':')
                n++;
            if (!n)
                return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: empty option of '%s'", m->name);
            sl_status st = append_options(m, p + j, n, err);
            if (st != SL_OK)
                return st;
            i = j + n;
        }
        if (!strcmp(m->name, VIEW_NO_CULLING) && m->options[0])
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: '%s' takes no options", VIEW_NO_CULLING);
        out->count++;
        if (!p[len])
            break;
        p += len + 1;
    }
    return SL_OK;
}

sl_status view_methods_add_options(view_methods *ms, const char *spec, sl_error *err)
{
    const char *colon = strchr(spec, ':');
    if (!colon || colon == spec || !colon[1])
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--method-options '%s': expected NAME:key=value,...", spec);
    view_method *m = find(ms, spec, (size_t)(colon - spec));
    if (!m)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--method-options: '%.*s' is not among the methods",
                         (int)(colon - spec), spec);
    if (!strcmp(m->name, VIEW_NO_CULLING))
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--method-options: '%s' takes no options", VIEW_NO_CULLING);
    return append_options(m, colon + 1, strlen(colon + 1), err);
}

sl_status view_methods_add_pvs(view_methods *ms, const char *file, sl_error *err)
{
    if (strpbrk(file, ", \t"))
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--pvs '%s': the file name may not hold a comma or a space",
                         file);
    view_method *m = find(ms, "pvs", 3);
    if (!m) {
        if (ms->count == VIEW_MAX_METHODS)
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--methods: at most %d methods", VIEW_MAX_METHODS);
        m = &ms->m[ms->count++];
        memset(m, 0, sizeof *m);
        snprintf(m->name, sizeof m->name, "pvs");
    }
    for (const char *p = m->options; *p; p += strcspn(p, ",") + (p[strcspn(p, ",")] ? 1 : 0))
        if (!strncmp(p, "file=", 5))
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--pvs: pvs is already given file= in --methods");
    char opt[1100];
    int n = snprintf(opt, sizeof opt, "file=%s", file);
    if (n < 0 || (size_t)n >= sizeof opt)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "--pvs: file name too long");
    return append_options(m, opt, (size_t)n, err);
}

/* ---- the camera controller ---- */

bool view_scene_walkable(sl_scene scene)
{
    sl_scene_stats s;
    sl_scene_get_stats(scene, &s);
    return s.has_terrain || s.street_edge_count > 0;
}

static float wrap_yaw(float yaw)
{
    double y = fmod((double)yaw + M_PI, 2 * M_PI);
    if (y < 0)
        y += 2 * M_PI;
    return (float)(y - M_PI);
}

void view_control_init(view_control *c, sl_scene scene, const sl_camera *start)
{
    memset(c, 0, sizeof *c);
    c->speed = 5.0f;
    c->eye_height = 1.7f;
    c->turn_rate = 90 * DEG;
    c->look_rate = 0.15f * DEG;
    c->can_walk = view_scene_walkable(scene);
    view_control_set(c, start);
    float above = start->position.z - sl_scene_ground_height(scene, start->position.x, start->position.y);
    c->walk = c->can_walk && above <= 5.0f;
    if (c->walk) {
        c->eye_height = above < MIN_EYE ? MIN_EYE : above;
        c->speed = 1.4f * 2; /* a brisk walk */
    }
}

void view_control_set(view_control *c, const sl_camera *cam)
{
    c->position = cam->position;
    c->yaw = wrap_yaw(cam->yaw);
    c->pitch = cam->pitch;
}

void view_control_step(view_control *c, sl_scene scene, const view_input *in, double dt)
{
    if (!(dt > 0))
        dt = 0;
    if (dt > 0.25)
        dt = 0.25; /* a stalled frame does not throw the camera across the city */
    float turn = c->turn_rate * (float)dt;
    c->yaw += (float)(in->turn_left - in->turn_right) * turn - (float)in->look_dx * c->look_rate;
    c->pitch += (float)(in->turn_up - in->turn_down) * turn - (float)in->look_dy * c->look_rate;
    c->yaw = wrap_yaw(c->yaw);
    if (c->pitch > 89 * DEG)
        c->pitch = 89 * DEG;
    if (c->pitch < -89 * DEG)
        c->pitch = -89 * DEG;
    float speed = c->speed * (in->fast ? 4.0f : 1.0f) * (in->slow ? 0.25f : 1.0f);
    float step = speed * (float)dt;
    float fwd = (float)(in->forward - in->back), side = (float)(in->right - in->left);
    float vert = (float)(in->up - in->down);
    float cy = cosf(c->yaw), sy = sinf(c->yaw), cp = cosf(c->pitch), sp = sinf(c->pitch);
    /* right of yaw: (sin yaw, -cos yaw, 0) */
    if (c->walk) {
        c->position.x += step * (fwd * cy + side * sy);
        c->position.y += step * (fwd * sy - side * cy);
        c->eye_height += step * vert;
        if (c->eye_height < MIN_EYE)
            c->eye_height = MIN_EYE;
        c->position.z = sl_scene_ground_height(scene, c->position.x, c->position.y) + c->eye_height;
    } else {
        c->position.x += step * (fwd * cp * cy + side * sy);
        c->position.y += step * (fwd * cp * sy - side * cy);
        c->position.z += step * (fwd * sp + vert);
    }
}

bool view_control_toggle_walk(view_control *c, sl_scene scene)
{
    if (c->walk || !c->can_walk) {
        c->walk = false;
        return false;
    }
    c->walk = true;
    c->eye_height = 1.7f;
    c->position.z = sl_scene_ground_height(scene, c->position.x, c->position.y) + c->eye_height;
    return true;
}

void view_control_scale_speed(view_control *c, float factor)
{
    c->speed *= factor;
    if (c->speed < 0.05f)
        c->speed = 0.05f;
    if (c->speed > 5000.0f)
        c->speed = 5000.0f;
}

sl_camera view_control_camera(const view_control *c, const sl_camera *intrinsics)
{
    sl_camera cam = *intrinsics;
    cam.position = c->position;
    cam.yaw = c->yaw;
    cam.pitch = c->pitch;
    cam.roll = 0;
    return cam;
}

/* ---- the HUD ---- */

typedef struct hud_buf {
    char *p;
    size_t size, used;
    uint32_t lines;
} hud_buf;

__attribute__((format(printf, 2, 3))) static void put(hud_buf *b, const char *fmt, ...)
{
    if (b->used + 1 >= b->size)
        return;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(b->p + b->used, b->size - b->used, fmt, ap);
    va_end(ap);
    if (n < 0)
        return;
    b->used = TOOL_MIN(b->used + (size_t)n, b->size - 1);
}

static void endline(hud_buf *b)
{
    put(b, "\n");
    b->lines++;
}

/* 1234 -> "1234", 12345 -> "12.3k", 1234567 -> "1.23M" */
static const char *count_text(uint64_t v, char *buf, size_t size)
{
    if (v < 10000)
        snprintf(buf, size, "%llu", (unsigned long long)v);
    else if (v < 1000000)
        snprintf(buf, size, "%.1fk", (double)v / 1e3);
    else
        snprintf(buf, size, "%.2fM", (double)v / 1e6);
    return buf;
}

uint32_t view_hud_text(const view_hud *h, char *buf, size_t size)
{
    hud_buf b = {buf, size, 0, 0};
    char t1[32], t2[32], t3[32];
    if (size)
        buf[0] = '\0';
    put(&b, "method %u/%u: %s", h->method_index + 1, h->method_count, h->method);
    if (h->guarantee)
        put(&b, " (%s)", h->guarantee);
    if (h->frozen)
        put(&b, "   FROZEN");
    if (h->map)
        put(&b, "   MAP");
    endline(&b);
    put(&b, "frame %.2f ms  cull %.2f ms  draw %.2f ms", h->frame_ms, h->cull_ms, h->draw_ms);
    if (h->gpu_ms >= 0)
        put(&b, "  gpu %.2f ms", h->gpu_ms);
    if (h->fps > 0)
        put(&b, "  %.1f fps", h->fps);
    endline(&b);
    put(&b, "objects %u/%u  triangles %s  draw calls %u  queries %s (stalls %s)", h->objects_drawn, h->objects_total,
        count_text(h->triangles_drawn, t1, sizeof t1), h->draw_calls, count_text(h->queries, t2, sizeof t2),
        count_text(h->query_stalls, t3, sizeof t3));
    endline(&b);
    /* the culler's own counters: those it uses */
    const sl_cull_stats *s = &h->cull;
    struct {
        const char *name;
        uint64_t v;
    } counters[] = {{"tested", s->objects_tested},      {"nodes", s->nodes_visited},
                    {"occlusion tests", s->occlusion_tests}, {"queries", s->queries},
                    {"pixels", s->pixels_rasterized},   {"pixel queries", s->pixel_queries}};
    bool any = false;
    for (size_t i = 0; i < TOOL_COUNTOF(counters); i++)
        if (counters[i].v) {
            put(&b, "%s%s %s", any ? "  " : "culler: ", counters[i].name, count_text(counters[i].v, t1, sizeof t1));
            any = true;
        }
    if (!any)
        put(&b, "culler: no counters");
    endline(&b);
    if (s->phase_count) {
        for (uint32_t i = 0; i < s->phase_count && i < SL_CULL_MAX_PHASES; i++)
            put(&b, "%s%s %.2f ms", i ? "  " : "phases: ", s->phase_names[i] ? s->phase_names[i] : "?", s->phase_ms[i]);
        endline(&b);
    }
    put(&b, "pos %.1f %.1f %.1f  yaw %.0f  pitch %.0f  %s %.1f m/s", (double)h->position.x, (double)h->position.y,
        (double)h->position.z, (double)(h->yaw / DEG), (double)(h->pitch / DEG), h->walk ? "walk" : "fly",
        (double)h->speed);
    endline(&b);
    if (h->recording) {
        put(&b, "REC %u poses", h->recorded);
        endline(&b);
    }
    if (h->message) {
        put(&b, "%s", h->message);
        endline(&b);
    }
    put(&b, "F1: keys");
    b.lines++;
    return b.lines;
}

const char view_keys_help[] =
    "  W A S D        move forward, left, back, right\n"
    "  E / Q          up / down (PageUp / PageDown too); walking: raise or lower the eye\n"
    "  mouse drag     look around (left button held); arrow keys turn too\n"
    "  Shift / Ctrl   4x faster / 4x slower while held\n"
    "  + / -          double / halve the speed\n"
    "  F              toggle walk (eye held over the ground) and fly\n"
    "  Tab / Shift+Tab  next / previous culling method; 1..9 pick one\n"
    "  Space          freeze culling: keep the frozen set and fly around it; the culled objects in\n"
    "                 the frozen frustum are ghosted in red, the frozen frustum drawn in yellow\n"
    "  G              ghosts: culled in the frustum / every culled object / none\n"
    "  M              toggle the top-down map (visible set highlighted, eye and frustum drawn)\n"
    "  R              start / stop recording the path (written when stopped, and at exit)\n"
    "  P or F12       screenshot (PNG, HUD included)\n"
    "  H              toggle the HUD;  F1: this list on screen\n"
    "  Esc            quit\n";

bool view_parse_size(const char *text, uint32_t *w, uint32_t *h)
{
    char *end;
    unsigned long a = strtoul(text, &end, 10);
    if (end == text || (*end != 'x' && *end != 'X') || text[0] == '-' || text[0] == '+')
        return false;
    const char *q = end + 1;
    if (*q == '-' || *q == '+')
        return false;
    unsigned long b = strtoul(q, &end, 10);
    if (end == q || *end || a < 16 || b < 16 || a > 16384 || b > 16384)
        return false;
    *w = (uint32_t)a;
    *h = (uint32_t)b;
    return true;
}

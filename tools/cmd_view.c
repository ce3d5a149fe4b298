/* `sightline view`: the walkthrough viewer. A GLFW window with an OpenGL 4.5 core context, the
 * renderer (render.h) on it, a culler per method to cycle through, walk/fly input, a HUD, freezing
 * the culling to fly around what was culled (ghosts and the frozen frustum), a top-down map, path
 * recording and screenshots; scripted runs (--frames, --path, --screenshot) for tests. The parts
 * that need no window are in tools/view_control.c; docs/viewer.md. */
#include "cli.h"
#include "view.h"

#include "tool.h"
#include "sightline/camera.h"
#include "sightline/import.h"
#include "sightline/path.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifdef SL_HAVE_VIEWER
#include "sightline/render.h"
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#endif

#define DEG (M_PI / 180.0)

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline view SCENE [--methods NAME[:key=value...],...] [--pvs FILE] [options]\n\n"
            "Walk or fly through a scene in a window, drawn by the OpenGL renderer with the culling\n"
            "method of your choice, and see what it culls. Needs a display and OpenGL 4.5 (Mesa's\n"
            "llvmpipe will do; under Xvfb: xvfb-run -a sightline view ...). docs/viewer.md.\n\n"
            "SCENE is city:tiny|small|vienna[:SEED] (generated on the fly), or a file: .slscene, a Quake\n"
            "III .bsp or .pk3 (with --map), or any format assimp reads.\n\n"
            "methods:\n"
            "  --methods LIST     methods to cycle through (Tab), comma-separated; each NAME or\n"
            "                     NAME:key=value[:key=value...] (options separated by colons); 'none'\n"
            "                     draws every object (default: none,vfc; `sightline methods` lists them)\n"
            "  --method-options NAME:key=value,...   options for one listed method (repeatable)\n"
            "  --pvs FILE         add the pvs method on FILE (a .slpvs of this scene)\n\n"
            "start and scripted runs:\n"
            "  --camera C         start at x,y,z,yaw,pitch,roll[,fov] (metres, degrees); default: the\n"
            "                     first street view of the scene (seed 1), or a spawn point, or above it\n"
            "  --path FILE        follow a path file (docs/paths.md), one pose per frame, instead of the\n"
            "                     input; the window takes the path's size unless --size; when the path\n"
            "                     ends, the input takes over (or, with --frames, the run ends)\n"
            "  --frames N         exit after N frames (default: run until closed; with --path and no\n"
            "                     --frames: until closed, the path played first)\n"
            "  --screenshot FILE  write the last frame (HUD and overlays included) as PNG at exit\n"
            "  --record FILE      record the path from the first frame; written at exit (and when R\n"
            "                     stops it); following --path, the recorded file is the path's poses\n"
            "  --size WxH         window size in pixels (default 1280x720)\n"
            "  --freeze-at N      freeze the culling at frame N (as Space does)\n"
            "  --keys N:KEY,...   press KEY at frame N (scripted input): tab, shift+tab, space, m, f, r,\n"
            "                     p, h, g, f1, plus, minus, 1..9, esc\n"
            "  --top-down         start with the top-down map\n"
            "  --ghosts MODE      frustum|all|none: which culled objects a frozen view ghosts (default frustum)\n"
            "  --fly              fly even where the scene could be walked\n"
            "  --no-hud           start without the HUD\n"
            "  --map NAME         map inside a .pk3\n"
            CLI_ALLOW_EXTERNAL_HELP
            "  --help             this text\n\n"
            "keys:\n%s\n"
            "HUD: method and guarantee; frame, cull and draw time (and GPU time where timer queries\n"
            "work); objects and triangles drawn, draw calls, occlusion queries and stalls; the culler's\n"
            "counters and phases; position, heading, walk/fly and speed.\n\n"
            "Without a display (GLFW cannot start or make a window) the command says so and exits 1, and\n"
            "so it does when the driver gives less than OpenGL 4.5 core. Exit status: 0 ok, 1 failure,\n"
            "2 usage error.\n\n"
            "examples:\n"
            "  sightline view city:small --methods none,vfc,hzb,cullmap\n"
            "  sightline view city.slscene --pvs city.slpvs --methods vfc\n"
            "  xvfb-run -a sightline view city:tiny --path walk.txt --frames 30 --screenshot shot.png\n",
            view_keys_help);
}

typedef struct view_args {
    const char *scene, *map, *methods, *camera, *path, *screenshot, *record, *pvs, *ghosts, *keys;
    const char *mopts[VIEW_MAX_METHODS];
    uint32_t mopt_count;
    uint32_t frames, width, height, freeze_at;
    bool has_frames, has_size, has_freeze, top_down, fly, no_hud;
    cli_import imp;
} view_args;

/* Parse the command line: -1 to go on, else the exit status. */
static int parse(int argc, char **argv, view_args *g)
{
    const char *cmd = argv[0];
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_common com = {0};
    const char *name, *val;
    memset(g, 0, sizeof *g);
    g->width = 1280, g->height = 720;
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_MAP, &com)) {
        } else if (!strcmp(name, "methods")) {
            g->methods = cli_value(&a, name, val);
        } else if (!strcmp(name, "method-options")) {
            const char *v = cli_value(&a, name, val);
            if (v && g->mopt_count == VIEW_MAX_METHODS) {
                cli_error(cmd, "--method-options: at most %d", VIEW_MAX_METHODS);
                return 2;
            }
            if (v)
                g->mopts[g->mopt_count++] = v;
        } else if (!strcmp(name, "pvs")) {
            g->pvs = cli_value(&a, name, val);
        } else if (!strcmp(name, "camera")) {
            g->camera = cli_value(&a, name, val);
        } else if (!strcmp(name, "path")) {
            g->path = cli_value(&a, name, val);
        } else if (!strcmp(name, "screenshot")) {
            g->screenshot = cli_value(&a, name, val);
        } else if (!strcmp(name, "record")) {
            g->record = cli_value(&a, name, val);
        } else if (!strcmp(name, "keys")) {
            g->keys = cli_value(&a, name, val);
        } else if (!strcmp(name, "ghosts")) {
            g->ghosts = cli_value(&a, name, val);
        } else if (!strcmp(name, "frames")) {
            g->has_frames = cli_parse_u32(&a, name, cli_value(&a, name, val), &g->frames);
        } else if (!strcmp(name, "freeze-at")) {
            g->has_freeze = cli_parse_u32(&a, name, cli_value(&a, name, val), &g->freeze_at);
        } else if (!strcmp(name, "size")) {
            const char *v = cli_value(&a, name, val);
            if (v && !view_parse_size(v, &g->width, &g->height)) {
                cli_error(cmd, "--size '%s': expected WxH, each 16 to 16384", v);
                return 2;
            }
            g->has_size = v != NULL;
        } else if (!strcmp(name, "top-down") && !val) {
            g->top_down = true;
        } else if (!strcmp(name, "fly") && !val) {
            g->fly = true;
        } else if (!strcmp(name, "no-hud") && !val) {
            g->no_hud = true;
        } else if (cli_import_option(&a, name, val, &g->imp)) {
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    g->scene = com.input, g->map = com.map;
    if (!g->scene) {
        cli_error(cmd, "missing SCENE (see --help)");
        return 2;
    }
    if (g->camera && g->path) {
        cli_error(cmd, "give --camera or --path, not both");
        return 2;
    }
    if (g->has_frames && !g->frames) {
        cli_error(cmd, "--frames: at least 1");
        return 2;
    }
    if (g->ghosts && strcmp(g->ghosts, "frustum") && strcmp(g->ghosts, "all") && strcmp(g->ghosts, "none")) {
        cli_error(cmd, "--ghosts '%s': expected frustum, all or none", g->ghosts);
        return 2;
    }
    if (g->camera) {
        sl_camera c = sl_camera_default();
        sl_error e;
        if (!sl_parse_camera_spec(g->camera, &c)) {
            cli_error(cmd, "--camera '%s': expected x,y,z,yaw,pitch,roll[,fov] (metres, degrees)", g->camera);
            return 2;
        }
        if (sl_camera_validate(&c, &e) != SL_OK) {
            cli_error(cmd, "--camera: %s", e.message);
            return 2;
        }
    }
    return -1;
}

#ifndef SL_HAVE_VIEWER

int sl_cmd_view(int argc, char **argv)
{
    view_args g;
    int parsed = parse(argc, argv, &g);
    if (parsed >= 0)
        return parsed;
    cli_error(argv[0], "this sightline was built without the viewer (it needs the OpenGL renderer and "
                       "libglfw3-dev; docs/viewer.md)");
    return 1;
}

#else

/* ---- the window's input ---- */

enum { GHOSTS_FRUSTUM, GHOSTS_ALL, GHOSTS_NONE };

typedef struct viewer {
    const char *cmd;
    sl_scene scene;
    sl_renderer r;
    GLFWwindow *win;
    uint32_t fb_w, fb_h;
    view_methods methods;
    sl_culler cullers[VIEW_MAX_METHODS];
    bool made[VIEW_MAX_METHODS];
    uint32_t current;
    sl_camera intrinsics;     /* fov, near, far, projection (viewport: the framebuffer's) */
    view_control ctl;
    uint32_t n;               /* objects */
    uint32_t *ids, count;     /* this frame's set */
    uint32_t *frozen, frozen_count, *ghost_ids;
    sl_view frozen_view;
    bool is_frozen, hud, help, map;
    int ghosts;
    /* keys pressed since the last frame */
    int method_step, method_pick;
    bool freeze_key, map_key, walk_key, record_key, shot_key, hud_key, help_key, ghost_key;
    float speed_factor;
    /* recording */
    sl_path rec;
    const char *rec_file;     /* --record, used by the first recording */
    char rec_name[64];
    double rec_wall;          /* wall time of the last pose recorded */
    uint32_t shots;
    char message[160];
    double message_until;
    /* mouse */
    bool dragging;
    double mouse_x, mouse_y;
} viewer;

static const char *glfw_error_text(void)
{
    const char *d = NULL;
    int code = glfwGetError(&d);
    return code != GLFW_NO_ERROR && d ? d : "no reason given";
}

/* A key pressed (from the window, or from --keys). */
static void press(viewer *v, int key, int mods)
{
    switch (key) {
    case GLFW_KEY_ESCAPE: glfwSetWindowShouldClose(v->win, GLFW_TRUE); break;
    case GLFW_KEY_TAB: v->method_step += (mods & GLFW_MOD_SHIFT) ? -1 : 1; break;
    case GLFW_KEY_SPACE: v->freeze_key = true; break;
    case GLFW_KEY_M: v->map_key = true; break;
    case GLFW_KEY_F: v->walk_key = true; break;
    case GLFW_KEY_R: v->record_key = true; break;
    case GLFW_KEY_P:
    case GLFW_KEY_F12: v->shot_key = true; break;
    case GLFW_KEY_H: v->hud_key = true; break;
    case GLFW_KEY_F1: v->help_key = true; break;
    case GLFW_KEY_G: v->ghost_key = true; break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD: v->speed_factor *= 2; break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: v->speed_factor *= 0.5f; break;
    default:
        if (key >= GLFW_KEY_1 && key <= GLFW_KEY_9)
            v->method_pick = key - GLFW_KEY_1 + 1;
        break;
    }
}

static void key_cb(GLFWwindow *w, int key, int scancode, int action, int mods)
{
    (void)scancode;
    viewer *v = glfwGetWindowUserPointer(w);
    if (action == GLFW_PRESS || (action == GLFW_REPEAT && (key == GLFW_KEY_EQUAL || key == GLFW_KEY_MINUS ||
                                                           key == GLFW_KEY_KP_ADD || key == GLFW_KEY_KP_SUBTRACT)))
        press(v, key, mods);
}

static bool down(GLFWwindow *w, int key) { return glfwGetKey(w, key) == GLFW_PRESS; }

static view_input poll_input(viewer *v)
{
    GLFWwindow *w = v->win;
    view_input in;
    memset(&in, 0, sizeof in);
    in.forward = down(w, GLFW_KEY_W), in.back = down(w, GLFW_KEY_S);
    in.left = down(w, GLFW_KEY_A), in.right = down(w, GLFW_KEY_D);
    in.up = down(w, GLFW_KEY_E) || down(w, GLFW_KEY_PAGE_UP);
    in.down = down(w, GLFW_KEY_Q) || down(w, GLFW_KEY_PAGE_DOWN);
    in.turn_left = down(w, GLFW_KEY_LEFT), in.turn_right = down(w, GLFW_KEY_RIGHT);
    in.turn_up = down(w, GLFW_KEY_UP), in.turn_down = down(w, GLFW_KEY_DOWN);
    in.fast = down(w, GLFW_KEY_LEFT_SHIFT) || down(w, GLFW_KEY_RIGHT_SHIFT);
    in.slow = down(w, GLFW_KEY_LEFT_CONTROL) || down(w, GLFW_KEY_RIGHT_CONTROL);
    double x, y;
    glfwGetCursorPos(w, &x, &y);
    bool pressed = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    if (pressed && v->dragging) {
        in.look_dx = x - v->mouse_x;
        in.look_dy = y - v->mouse_y;
    }
    v->dragging = pressed;
    v->mouse_x = x, v->mouse_y = y;
    return in;
}

static void note(viewer *v, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void note(viewer *v, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(v->message, sizeof v->message, fmt, ap);
    va_end(ap);
    v->message_until = tool_now() + 4;
    fprintf(stderr, "sightline view: %s\n", v->message);
}

/* ---- --keys N:KEY,... ---- */

#define VIEW_MAX_KEYS 64
typedef struct scripted_key {
    uint32_t frame;
    int key, mods;
} scripted_key;

static const struct {
    const char *name;
    int key, mods;
} key_names[] = {{"tab", GLFW_KEY_TAB, 0}, {"shift+tab", GLFW_KEY_TAB, GLFW_MOD_SHIFT}, {"space", GLFW_KEY_SPACE, 0},
                 {"m", GLFW_KEY_M, 0},     {"f", GLFW_KEY_F, 0},     {"r", GLFW_KEY_R, 0},
                 {"p", GLFW_KEY_P, 0},     {"h", GLFW_KEY_H, 0},     {"g", GLFW_KEY_G, 0},
                 {"f1", GLFW_KEY_F1, 0},   {"plus", GLFW_KEY_EQUAL, 0}, {"minus", GLFW_KEY_MINUS, 0},
                 {"esc", GLFW_KEY_ESCAPE, 0}};

/* false after a usage error */
static bool parse_keys(const char *cmd, const char *text, scripted_key *out, uint32_t *count)
{
    *count = 0;
    for (const char *p = text; p && *p;) {
        size_t len = strcspn(p, ",");
        char item[32];
        if (len == 0 || len >= sizeof item || *count == VIEW_MAX_KEYS)
            goto bad;
        memcpy(item, p, len);
        item[len] = '\0';
        char *colon = strchr(item, ':'), *end;
        if (!colon || colon == item || item[0] == '-' || item[0] == '+')
            goto bad;
        *colon = '\0';
        unsigned long frame = strtoul(item, &end, 10);
        if (*end || frame > UINT32_MAX)
            goto bad;
        const char *k = colon + 1;
        int key = -1, mods = 0;
        if (k[0] >= '1' && k[0] <= '9' && !k[1])
            key = GLFW_KEY_1 + (k[0] - '1');
        for (size_t i = 0; key < 0 && i < TOOL_COUNTOF(key_names); i++)
            if (!strcmp(k, key_names[i].name))
                key = key_names[i].key, mods = key_names[i].mods;
        if (key < 0)
            goto bad;
        out[(*count)++] = (scripted_key){(uint32_t)frame, key, mods};
        p += len + (p[len] ? 1 : 0);
    }
    return true;
bad:
    cli_error(cmd, "--keys '%s': expected N:KEY,... (at most %d; keys: tab, shift+tab, space, m, f, r, p, h, g, f1, "
                   "plus, minus, 1..9, esc)", text, VIEW_MAX_KEYS);
    return false;
}

/* ---- cullers ---- */

static bool is_render_method(const char *name)
{
    for (uint32_t i = 0; i < sl_render_method_count(); i++) {
        const sl_cull_method_desc *d = sl_render_method(i);
        if (d && d->name && !strcmp(d->name, name))
            return true;
    }
    return false;
}

/* The culler of method i (made on first use); NULL for "none". */
static sl_status culler_of(viewer *v, uint32_t i, sl_culler *out, sl_error *err)
{
    if (!v->made[i] && strcmp(v->methods.m[i].name, VIEW_NO_CULLING)) {
        sl_status st = sl_renderer_create_culler(v->r, v->methods.m[i].name, v->methods.m[i].options, &v->cullers[i], err);
        if (st != SL_OK)
            return st;
    }
    v->made[i] = true;
    *out = v->cullers[i];
    return SL_OK;
}

/* ---- recording and screenshots ---- */

/* The first name PREFIX-NNNN.EXT that does not exist. */
static void free_name(const char *prefix, const char *ext, uint32_t *counter, char *buf, size_t size)
{
    do
        snprintf(buf, size, "%s-%04u.%s", prefix, ++*counter, ext);
    while (access(buf, F_OK) == 0 && *counter < 9999);
}

static sl_status record_start(viewer *v, sl_error *err)
{
    sl_camera in = v->intrinsics;
    in.width = v->fb_w, in.height = v->fb_h;
    sl_status st = sl_path_create(&in, NULL, &v->rec, err);
    v->rec_wall = tool_now();
    return st;
}

static sl_status record_stop(viewer *v, sl_error *err)
{
    if (!v->rec)
        return SL_OK;
    uint32_t counter = 0;
    const char *file = v->rec_file;
    if (!file) {
        free_name("view-path", "txt", &counter, v->rec_name, sizeof v->rec_name);
        file = v->rec_name;
    }
    v->rec_file = NULL;
    uint32_t poses = sl_path_count(v->rec);
    sl_status st = sl_path_save(v->rec, file, err);
    sl_path_destroy(v->rec);
    v->rec = NULL;
    if (st == SL_OK)
        note(v, "recorded %u poses into %s", poses, file);
    return st;
}

/* ---- drawing ---- */

static sl_aabb scene_box(sl_scene s)
{
    sl_aabb b = sl_scene_bounds(s);
    if (!(b.max.x >= b.min.x)) /* empty */
        b.min = (sl_vec3){-10, -10, 0}, b.max = (sl_vec3){10, 10, 10};
    return b;
}

/* The 12 edges of a view's frustum, the far end cut at `reach` metres (6 floats a segment). */
static uint32_t frustum_segments(const sl_view *view, double reach, float *seg)
{
    const sl_vec3 *c = view->frustum.corners;
    double n = view->near_plane, f = view->far_plane;
    double t = (isfinite(f) && f > n) ? fmin(1.0, (reach - n) / (f - n)) : 0;
    if (t < 0)
        t = 0;
    sl_vec3 far[4];
    for (int i = 0; i < 4; i++) {
        if (!isfinite(c[4 + i].x) || !isfinite(c[4 + i].y) || !isfinite(c[4 + i].z))
            far[i] = c[i];
        else
            far[i] = (sl_vec3){(float)(c[i].x + t * (c[4 + i].x - c[i].x)), (float)(c[i].y + t * (c[4 + i].y - c[i].y)),
                               (float)(c[i].z + t * (c[4 + i].z - c[i].z))};
    }
    uint32_t k = 0;
#define SEG(a, b)                                                                                                   \
    do {                                                                                                            \
        seg[k * 6 + 0] = (a).x, seg[k * 6 + 1] = (a).y, seg[k * 6 + 2] = (a).z;                                     \
        seg[k * 6 + 3] = (b).x, seg[k * 6 + 4] = (b).y, seg[k * 6 + 5] = (b).z;                                     \
        k++;                                                                                                        \
    } while (0)
    sl_vec3 eye = view->projection == SL_PERSPECTIVE ? view->eye : c[0];
    for (int i = 0; i < 4; i++) {
        SEG(c[i], c[(i + 1) % 4]);
        SEG(far[i], far[(i + 1) % 4]);
        SEG(view->projection == SL_PERSPECTIVE ? eye : c[i], far[i]);
    }
#undef SEG
    return k;
}

/* The top-down map's camera: orthographic, from above the scene's bounds, north up. Indoors (a
 * scene with BSP data: a Quake III map) it starts 1 m above the eye, so that the ceilings above
 * do not hide the floor plan. */
static sl_status map_view(viewer *v, double eye_z, sl_view *out, sl_error *err)
{
    sl_aabb b = scene_box(v->scene);
    double ex = b.max.x - b.min.x, ey = b.max.y - b.min.y, ez = b.max.z - b.min.z;
    double aspect = (double)v->fb_w / v->fb_h;
    sl_camera m = sl_camera_default();
    m.projection = SL_ORTHOGRAPHIC;
    m.position = (sl_vec3){(float)(b.min.x + ex / 2), (float)(b.min.y + ey / 2), (float)(b.max.z + 10)};
    m.yaw = (float)(M_PI / 2);
    m.pitch = -(float)(M_PI / 2);
    m.ortho_height = (float)(1.05 * fmax(1.0, fmax(ey, ex / aspect)));
    m.near_plane = 1;
    m.far_plane = (float)(ez + 20);
    sl_scene_stats ss;
    sl_scene_get_stats(v->scene, &ss);
    if (ss.has_bsp && eye_z + 1 < m.position.z - 1)
        m.near_plane = (float)(m.position.z - (eye_z + 1));
    m.width = v->fb_w, m.height = v->fb_h;
    return sl_view_from_camera(&m, out, err);
}

/* The objects a frozen view ghosts: culled ones (in its frustum, or all). */
static uint32_t ghost_set(viewer *v)
{
    const sl_aabb *boxes = sl_scene_object_bounds_array(v->scene);
    uint32_t k = 0, j = 0;
    for (uint32_t id = 0; id < v->n; id++) {
        while (j < v->frozen_count && v->frozen[j] < id)
            j++;
        if (j < v->frozen_count && v->frozen[j] == id)
            continue;
        if (v->ghosts == GHOSTS_FRUSTUM && !sl_frustum_test_aabb(&v->frozen_view.frustum, &boxes[id]))
            continue;
        v->ghost_ids[k++] = id;
    }
    return k;
}

static double scene_reach(sl_scene s)
{
    sl_aabb b = scene_box(s);
    double dx = b.max.x - b.min.x, dy = b.max.y - b.min.y, dz = b.max.z - b.min.z;
    return fmax(50.0, sqrt(dx * dx + dy * dy + dz * dz));
}

#define GHOST_RGBA 0xff303070u
#define FRUSTUM_RGBA 0xffe020ffu
#define VISIBLE_RGBA 0xffb00080u
#define EYE_RGBA 0x20ff20ffu
#define HUD_RGBA 0xffffffffu
#define SHADOW_RGBA 0x000000ffu

/* One frame: cull and draw (or draw the frozen set), overlays, HUD. */
static sl_status draw_frame(viewer *v, const sl_view *view, sl_render_frame_stats *st, sl_error *err)
{
    sl_status s;
    sl_culler c;
    if ((s = culler_of(v, v->current, &c, err)) != SL_OK)
        return s;
    memset(st, 0, sizeof *st);
    if (v->is_frozen) {
        if ((s = sl_renderer_draw(v->r, view, v->frozen, v->frozen_count, SL_RENDER_SHADED, st, err)) != SL_OK)
            return s;
    } else {
        if ((s = sl_renderer_frame(v->r, c, view, SL_RENDER_SHADED, v->ids, &v->count, st, err)) != SL_OK)
            return s;
        if (!c) { /* no culler: every object */
            for (uint32_t i = 0; i < v->n; i++)
                v->ids[i] = i;
            v->count = v->n;
        }
    }
    const sl_view *culled_from = v->is_frozen ? &v->frozen_view : view;
    const uint32_t *set = v->is_frozen ? v->frozen : v->ids;
    uint32_t set_count = v->is_frozen ? v->frozen_count : v->count;
    float seg[12 * 6 + 6 * 6];
    if (v->map) {
        sl_view mv;
        if ((s = map_view(v, view->eye.z, &mv, err)) != SL_OK)
            return s;
        /* every object, then the visible set highlighted */
        for (uint32_t i = 0; i < v->n; i++)
            v->ghost_ids[i] = i;
        if ((s = sl_renderer_draw(v->r, &mv, v->ghost_ids, v->n, SL_RENDER_SHADED, NULL, err)) != SL_OK ||
            (s = sl_renderer_draw_ghosts(v->r, &mv, set, set_count, VISIBLE_RGBA, err)) != SL_OK)
            return s;
        uint32_t k = frustum_segments(culled_from, scene_reach(v->scene) * 0.25, seg);
        float top = (float)(mv.camera.position.z - mv.camera.near_plane - 0.5); /* just below the near plane */
        for (uint32_t i = 0; i < k; i++)
            seg[i * 6 + 2] = seg[i * 6 + 5] = top;
        if ((s = sl_renderer_draw_lines(v->r, &mv, seg, k, FRUSTUM_RGBA, err)) != SL_OK)
            return s;
        float r = (float)(mv.camera.ortho_height / 60), x = view->eye.x, y = view->eye.y;
        float eye[12] = {x - r, y, top, x + r, y, top, x, y - r, top, x, y + r, top};
        if ((s = sl_renderer_draw_lines(v->r, &mv, eye, 2, EYE_RGBA, err)) != SL_OK)
            return s;
    } else if (v->is_frozen) {
        uint32_t k = v->ghosts == GHOSTS_NONE ? 0 : ghost_set(v);
        if (k && (s = sl_renderer_draw_ghosts(v->r, view, v->ghost_ids, k, GHOST_RGBA, err)) != SL_OK)
            return s;
        uint32_t nseg = frustum_segments(&v->frozen_view, scene_reach(v->scene), seg);
        if ((s = sl_renderer_draw_lines(v->r, view, seg, nseg, FRUSTUM_RGBA, err)) != SL_OK)
            return s;
    }
    return SL_OK;
}

static sl_status draw_hud(viewer *v, const sl_render_frame_stats *st, double fps, sl_error *err)
{
    float scale = v->fb_h >= 700 ? 2.0f : 1.0f; /* whole pixels a font unit: even strokes */
    sl_status s = SL_OK;
    if (v->hud) {
        view_hud h;
        memset(&h, 0, sizeof h);
        sl_culler c = v->cullers[v->current];
        h.method = v->methods.m[v->current].name;
        h.guarantee = c ? sl_cull_guarantee_name(sl_culler_guarantee(c)) : NULL;
        h.method_index = v->current, h.method_count = v->methods.count;
        h.frozen = v->is_frozen, h.walk = v->ctl.walk, h.recording = v->rec != NULL, h.map = v->map;
        h.recorded = v->rec ? sl_path_count(v->rec) : 0;
        h.frame_ms = st->frame_ms, h.cull_ms = st->cull_ms, h.draw_ms = st->draw_ms;
        h.gpu_ms = st->gpu_draw_ms >= 0 ? st->gpu_draw_ms + (st->gpu_query_ms > 0 ? st->gpu_query_ms : 0) : -1;
        h.objects_drawn = st->objects_drawn, h.objects_total = v->n, h.draw_calls = st->draw_calls;
        h.triangles_drawn = st->triangles_drawn, h.queries = st->queries, h.query_stalls = st->query_stalls;
        h.cull = st->cull;
        h.position = v->ctl.position, h.yaw = v->ctl.yaw, h.pitch = v->ctl.pitch, h.speed = v->ctl.speed;
        h.fps = fps;
        h.message = tool_now() < v->message_until ? v->message : NULL;
        char text[2048];
        view_hud_text(&h, text, sizeof text);
        if ((s = sl_renderer_draw_text(v->r, 8 + scale, 8 + scale, scale, text, SHADOW_RGBA, err)) != SL_OK ||
            (s = sl_renderer_draw_text(v->r, 8, 8, scale, text, HUD_RGBA, err)) != SL_OK)
            return s;
    }
    if (v->help) {
        float x = (float)v->fb_w / 2 - 130 * scale, y = 8;
        if (x < 8)
            x = 8;
        char text[2048];
        snprintf(text, sizeof text, "keys:\n%s", view_keys_help);
        if ((s = sl_renderer_draw_text(v->r, x + scale, y + scale, scale, text, SHADOW_RGBA, err)) != SL_OK ||
            (s = sl_renderer_draw_text(v->r, x, y, scale, text, 0xffff80ffu, err)) != SL_OK)
            return s;
    }
    return s;
}

/* The keys pressed since the last frame. */
static sl_status handle_keys(viewer *v, const sl_view *view, sl_error *err)
{
    sl_status s = SL_OK;
    uint32_t want = v->current;
    if (v->method_step)
        want = (uint32_t)(((int64_t)v->current + v->method_step % (int)v->methods.count + v->methods.count) %
                          v->methods.count);
    if (v->method_pick && (uint32_t)v->method_pick <= v->methods.count)
        want = (uint32_t)v->method_pick - 1;
    if (want != v->current) {
        sl_culler c;
        sl_error e;
        if (culler_of(v, want, &c, &e) != SL_OK)
            note(v, "%s: %s", v->methods.m[want].name, e.message);
        else {
            v->current = want;
            note(v, "method %s", v->methods.m[want].name);
        }
    }
    if (v->freeze_key) {
        v->is_frozen = !v->is_frozen;
        if (v->is_frozen) {
            memcpy(v->frozen, v->ids, (size_t)v->count * sizeof *v->ids);
            v->frozen_count = v->count;
            v->frozen_view = *view;
        }
        if (v->is_frozen)
            note(v, "culling frozen (%u objects)", v->frozen_count);
        else
            note(v, "culling live");
    }
    if (v->map_key)
        v->map = !v->map;
    if (v->walk_key)
        note(v, view_control_toggle_walk(&v->ctl, v->scene) ? "walk" : v->ctl.can_walk ? "fly" : "fly (nothing to walk on)");
    if (v->hud_key)
        v->hud = !v->hud;
    if (v->help_key)
        v->help = !v->help;
    if (v->ghost_key) {
        v->ghosts = (v->ghosts + 1) % 3;
        note(v, "ghosts: %s", v->ghosts == GHOSTS_FRUSTUM ? "culled in the frozen frustum"
                              : v->ghosts == GHOSTS_ALL  ? "every culled object"
                                                         : "none");
    }
    if (v->speed_factor != 1.0f)
        view_control_scale_speed(&v->ctl, v->speed_factor);
    if (v->record_key) {
        if (v->rec)
            s = record_stop(v, err);
        else if ((s = record_start(v, err)) == SL_OK)
            note(v, "recording");
    }
    v->method_step = v->method_pick = 0;
    v->freeze_key = v->map_key = v->walk_key = v->record_key = v->hud_key = v->help_key = v->ghost_key = false;
    v->speed_factor = 1.0f;
    return s;
}

/* The start camera: --camera, the path's first pose, else the scene's first street view (seed 1,
 * or a Quake III spawn point), else a view from above. */
static sl_camera start_camera(sl_scene scene, const view_args *g, sl_path path)
{
    sl_camera cam = sl_camera_default();
    if (g->camera) {
        sl_parse_camera_spec(g->camera, &cam);
        return cam;
    }
    if (path && sl_path_count(path))
        return sl_path_camera(path, 0);
    sl_path p = NULL;
    if (sl_path_random_views(scene, SL_VIEWS_STREET, 1, 1, NULL, NULL, &p, NULL) == SL_OK && sl_path_count(p)) {
        cam = sl_path_camera(p, 0);
        sl_path_destroy(p);
        return cam;
    }
    sl_path_destroy(p);
    p = NULL;
    if (sl_path_random_views(scene, SL_VIEWS_FLYOVER, 1, 1, NULL, NULL, &p, NULL) == SL_OK && sl_path_count(p))
        cam = sl_path_camera(p, 0);
    sl_path_destroy(p);
    return cam;
}

static int run(viewer *v, const view_args *g, sl_path path, const scripted_key *keys, uint32_t key_count)
{
    const char *cmd = v->cmd;
    sl_error err;
    sl_camera start = start_camera(v->scene, g, path);
    view_control_init(&v->ctl, v->scene, &start);
    if (g->fly)
        v->ctl.walk = false;
    sl_status s = SL_OK;
    if (g->record) {
        v->rec_file = g->record;
        s = record_start(v, &err);
    }
    uint32_t frame = 0;
    double last = tool_now(), fps_t0 = last, fps = 0;
    uint32_t fps_frames = 0;
    sl_render_frame_stats st;
    memset(&st, 0, sizeof st);
    bool drew = false;
    while (s == SL_OK && !glfwWindowShouldClose(v->win) && !(g->has_frames && frame >= g->frames)) {
        glfwPollEvents();
        double now = tool_now(), dt = now - last;
        last = now;
        int w, h;
        glfwGetFramebufferSize(v->win, &w, &h);
        if (w > 0 && h > 0 && ((uint32_t)w != v->fb_w || (uint32_t)h != v->fb_h)) {
            if ((s = sl_renderer_resize(v->r, (uint32_t)w, (uint32_t)h, &err)) != SL_OK)
                break;
            v->fb_w = (uint32_t)w, v->fb_h = (uint32_t)h;
        }
        bool following = path && frame < sl_path_count(path);
        view_input in = poll_input(v);
        if (following)
            view_control_set(&v->ctl, &(sl_camera){.position = sl_path_poses(path)[frame].position,
                                                   .yaw = sl_path_poses(path)[frame].yaw,
                                                   .pitch = sl_path_poses(path)[frame].pitch});
        else
            view_control_step(&v->ctl, v->scene, &in, dt);
        sl_camera cam = view_control_camera(&v->ctl, &v->intrinsics);
        if (following)
            cam = sl_path_camera(path, frame); /* roll included, bit for bit */
        cam.width = v->fb_w, cam.height = v->fb_h;
        sl_view view;
        if ((s = sl_view_from_camera(&cam, &view, &err)) != SL_OK)
            break;
        if (g->has_freeze && frame == g->freeze_at)
            v->freeze_key = true;
        for (uint32_t k = 0; k < key_count; k++)
            if (keys[k].frame == frame)
                press(v, keys[k].key, keys[k].mods);
        if ((s = draw_frame(v, &view, &st, &err)) != SL_OK)
            break;
        /* keys act after the frame they were pressed in was culled (freeze keeps its set) */
        if ((s = handle_keys(v, &view, &err)) != SL_OK)
            break;
        if (v->rec) {
            /* following: the path's own times; else wall time, going on from the last pose recorded
             * (a recording that started on the path and goes on by hand keeps its times in order) */
            uint32_t have = sl_path_count(v->rec);
            double t = following ? sl_path_poses(path)[frame].time
                       : have    ? sl_path_poses(v->rec)[have - 1].time + (now - v->rec_wall)
                                 : 0.0;
            v->rec_wall = now;
            sl_pose q = {(float)t, cam.position, cam.yaw, cam.pitch, cam.roll};
            if ((s = sl_path_append(v->rec, &q, &err)) != SL_OK)
                break;
        }
        fps_frames++;
        if (now - fps_t0 >= 1.0) {
            fps = fps_frames / (now - fps_t0);
            fps_t0 = now, fps_frames = 0;
        }
        if ((s = draw_hud(v, &st, fps, &err)) != SL_OK)
            break;
        drew = true;
        if (v->shot_key) {
            char name[64];
            free_name("view", "png", &v->shots, name, sizeof name);
            if ((s = sl_renderer_write_png(v->r, name, &err)) != SL_OK)
                break;
            note(v, "saved %s", name);
            v->shot_key = false;
        }
        if ((s = sl_renderer_present(v->r, v->fb_w, v->fb_h, &err)) != SL_OK)
            break;
        glfwSwapBuffers(v->win);
        frame++;
    }
    if (s == SL_OK && g->screenshot && drew)
        s = sl_renderer_write_png(v->r, g->screenshot, &err);
    sl_error rerr;
    if (s == SL_OK)
        s = record_stop(v, &err);
    else
        record_stop(v, &rerr);
    if (s != SL_OK)
        return cli_fail(cmd, &err);
    printf("%u frames, last: %u of %u objects drawn, %.2f ms a frame (%s)\n", frame, st.objects_drawn, v->n,
           st.frame_ms, v->methods.m[v->current].name);
    return 0;
}

int sl_cmd_view(int argc, char **argv)
{
    const char *cmd = argv[0];
    view_args g;
    int parsed = parse(argc, argv, &g);
    if (parsed >= 0)
        return parsed;
    viewer v;
    memset(&v, 0, sizeof v);
    v.cmd = cmd;
    v.hud = !g.no_hud;
    v.map = g.top_down;
    v.speed_factor = 1.0f;
    v.ghosts = !g.ghosts || !strcmp(g.ghosts, "frustum") ? GHOSTS_FRUSTUM : !strcmp(g.ghosts, "all") ? GHOSTS_ALL
                                                                                                     : GHOSTS_NONE;
    sl_error err;
    if (view_methods_parse(g.methods, is_render_method, &v.methods, &err) != SL_OK) {
        cli_error(cmd, "%s", err.message);
        return 2;
    }
    for (uint32_t i = 0; i < g.mopt_count; i++)
        if (view_methods_add_options(&v.methods, g.mopts[i], &err) != SL_OK) {
            cli_error(cmd, "%s", err.message);
            return 2;
        }
    if (g.pvs && view_methods_add_pvs(&v.methods, g.pvs, &err) != SL_OK) {
        cli_error(cmd, "%s", err.message);
        return 2;
    }
    for (uint32_t i = 0; i < v.methods.count; i++)
        if (!is_render_method(v.methods.m[i].name) && strcmp(v.methods.m[i].name, VIEW_NO_CULLING) &&
            sl_cull_method_check_options(v.methods.m[i].name, v.methods.m[i].options, &err) != SL_OK) {
            cli_error(cmd, "%s", err.message);
            return 2;
        }
    scripted_key keys[VIEW_MAX_KEYS];
    uint32_t key_count = 0;
    if (g.keys && !parse_keys(cmd, g.keys, keys, &key_count))
        return 2;
    /* the path and the scene before the window: their errors need no display */
    sl_path path = NULL;
    if (g.path && sl_path_load(g.path, NULL, &path, &err) != SL_OK)
        return cli_fail(cmd, &err);
    v.intrinsics = path ? sl_path_intrinsics(path) : sl_camera_default();
    if (g.camera) {
        sl_camera c = sl_camera_default();
        sl_parse_camera_spec(g.camera, &c);
        v.intrinsics.fov_y = c.fov_y;
    }
    uint32_t w = g.width, h = g.height;
    if (path && !g.has_size)
        w = v.intrinsics.width, h = v.intrinsics.height;
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&g.imp, &io);
    if (cli_open_scene(g.scene, g.map, &io, NULL, &v.scene, NULL, 0, &err) != SL_OK) {
        sl_path_destroy(path);
        return cli_fail(cmd, &err);
    }
    v.n = sl_scene_object_count(v.scene);
    size_t n1 = v.n ? v.n : 1;
    v.ids = calloc(n1, sizeof *v.ids);
    v.frozen = calloc(n1, sizeof *v.frozen);
    v.ghost_ids = calloc(n1, sizeof *v.ghost_ids);
    int rc = 1;
    if (!v.ids || !v.frozen || !v.ghost_ids) {
        cli_error(cmd, "out of memory");
        goto done;
    }
    /* the window: GLFW, an OpenGL 4.5 core context */
    if (!glfwInit()) {
        cli_error(cmd, "no display: GLFW could not start (%s); run it on a desktop, or under Xvfb: "
                       "xvfb-run -a sightline view ...", glfw_error_text());
        goto done;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_DEPTH_BITS, 0);
    char title[256];
    snprintf(title, sizeof title, "sightline view %s", g.scene);
    v.win = glfwCreateWindow((int)w, (int)h, title, NULL, NULL);
    if (!v.win) {
        const char *d = NULL;
        int code = glfwGetError(&d);
        if (code == GLFW_VERSION_UNAVAILABLE || code == GLFW_API_UNAVAILABLE)
            cli_error(cmd, "the driver gives no OpenGL 4.5 core context (%s); the viewer needs OpenGL 4.5",
                      d ? d : "no reason given");
        else
            cli_error(cmd, "no display: GLFW could not make a window with an OpenGL 4.5 core context (%s)",
                      d ? d : "no reason given");
        goto done_glfw;
    }
    int major = glfwGetWindowAttrib(v.win, GLFW_CONTEXT_VERSION_MAJOR);
    int minor = glfwGetWindowAttrib(v.win, GLFW_CONTEXT_VERSION_MINOR);
    if (major < 4 || (major == 4 && minor < 5) ||
        glfwGetWindowAttrib(v.win, GLFW_OPENGL_PROFILE) != GLFW_OPENGL_CORE_PROFILE) {
        cli_error(cmd, "the driver gave OpenGL %d.%d%s; the viewer needs OpenGL 4.5 core", major, minor,
                  glfwGetWindowAttrib(v.win, GLFW_OPENGL_PROFILE) == GLFW_OPENGL_CORE_PROFILE ? " core" : "");
        goto done_glfw;
    }
    glfwMakeContextCurrent(v.win);
    glfwSwapInterval(g.has_frames ? 0 : 1);
    glfwSetWindowUserPointer(v.win, &v);
    glfwSetKeyCallback(v.win, key_cb);
    {
        int fw, fh;
        glfwGetFramebufferSize(v.win, &fw, &fh);
        v.fb_w = fw > 0 ? (uint32_t)fw : w, v.fb_h = fh > 0 ? (uint32_t)fh : h;
    }
    sl_renderer_options ro;
    sl_renderer_options_default(&ro);
    ro.context = SL_GL_CONTEXT_CURRENT;
    ro.width = v.fb_w, ro.height = v.fb_h;
    if (sl_renderer_create(v.scene, &ro, NULL, &v.r, &err) != SL_OK) {
        rc = cli_fail(cmd, &err);
        goto done_glfw;
    }
    /* the first method's culler now: a bad file or option fails before the first frame */
    {
        sl_culler c;
        if (culler_of(&v, 0, &c, &err) != SL_OK) {
            rc = cli_fail(cmd, &err);
            goto done_glfw;
        }
    }
    rc = run(&v, &g, path, keys, key_count);
done_glfw:
    for (uint32_t i = 0; i < v.methods.count; i++)
        sl_culler_destroy(v.cullers[i]);
    sl_renderer_destroy(v.r);
    if (v.win)
        glfwDestroyWindow(v.win);
    glfwTerminate();
done:
    free(v.ids);
    free(v.frozen);
    free(v.ghost_ids);
    sl_scene_destroy(v.scene);
    sl_path_destroy(path);
    return rc;
}

#endif

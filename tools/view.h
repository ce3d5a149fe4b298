/* The parts of `sightline view` that need no window (tools/view_control.c): the list of methods
 * to cycle through, the walk/fly camera controller, the HUD's text and the recorded path. The
 * window, the input and the drawing are in tools/cmd_view.c. Every function is pure or works on
 * its own arguments only (thread-safe on distinct arguments). */
#ifndef SL_TOOLS_VIEW_H
#define SL_TOOLS_VIEW_H

#include "sightline/camera.h"
#include "sightline/core.h"
#include "sightline/cull.h"
#include "sightline/path.h"
#include "sightline/scene.h"

#include <stdbool.h>
#include <stdint.h>

/* ---- methods: --methods NAME[:key=value...],... plus --method-options NAME:key=value,... ---- */
#define VIEW_MAX_METHODS 16
#define VIEW_NO_CULLING "none" /* the pseudo-method that draws every object (no culler) */
typedef struct view_method {
    char name[64];
    char options[1024]; /* "key=value,key=value" for sl_culler_create ("" for the defaults) */
} view_method;
typedef struct view_methods {
    view_method m[VIEW_MAX_METHODS];
    uint32_t count;
} view_methods;
/* Parse a --methods list: comma-separated methods, each NAME or NAME:key=value[:key=value...]
 * (the options separated by colons, since commas separate the methods). NULL: the default list
 * (none, vfc). Each name must be registered (sl_cull_method_find), "none", or one of the
 * renderer's own methods, which is_render_method tells (may be NULL: none). Errors name the
 * method. */
sl_status view_methods_parse(const char *text, bool (*is_render_method)(const char *name), view_methods *out,
                             sl_error *err);
/* --method-options NAME:key=value,...: append these options to NAME's (NAME must be listed). */
sl_status view_methods_add_options(view_methods *ms, const char *spec, sl_error *err);
/* --pvs FILE: the pvs method with file=FILE (appended, or given file= when listed without one). */
sl_status view_methods_add_pvs(view_methods *ms, const char *file, sl_error *err);

/* ---- the camera controller ---- */
typedef struct view_input {
    bool forward, back, left, right, up, down; /* W S A D, E/PageUp, Q/PageDown held */
    bool turn_left, turn_right, turn_up, turn_down; /* arrow keys held */
    bool fast, slow;                            /* Shift, Ctrl held */
    double look_dx, look_dy;                    /* mouse motion while looking, pixels (right, down) */
} view_input;

typedef struct view_control {
    sl_vec3 position;
    float yaw, pitch;         /* radians */
    float speed;              /* metres per second without Shift/Ctrl (default 5) */
    float eye_height;         /* walk: eye above sl_scene_ground_height (1.7 m) */
    float turn_rate;          /* arrow keys, radians per second (default 90 degrees) */
    float look_rate;          /* mouse, radians per pixel (default 0.15 degrees) */
    bool walk;                /* walk (eye held over the ground) or fly */
    bool can_walk;            /* the scene has ground to walk on: terrain or streets */
} view_control;

/* Can one walk in this scene: does it have a terrain or a street network? */
bool view_scene_walkable(sl_scene scene);
/* Start at a camera: walk when the scene is walkable and the eye is within 5 m of the ground
 * (the eye height is then the camera's, at least 0.3 m), else fly. */
void view_control_init(view_control *c, sl_scene scene, const sl_camera *start);
/* Advance by dt seconds of held keys and mouse motion. Walking moves on the ground plane and puts
 * the eye at eye_height over the ground; flying moves along the view direction; up/down move
 * along +Z in both (walking: they change the eye height, never below 0.3 m). Pitch stays within
 * +-89 degrees; yaw is kept in [-180, 180) degrees. */
void view_control_step(view_control *c, sl_scene scene, const view_input *in, double dt);
/* Toggle walk/fly (walk only where can_walk; returns the new walk state). */
bool view_control_toggle_walk(view_control *c, sl_scene scene);
/* Speed keys: factor 2 faster or slower, within [0.05, 5000] m/s. */
void view_control_scale_speed(view_control *c, float factor);
/* The camera: intrinsics (fov, near, far, projection, viewport) with the controller's pose. */
sl_camera view_control_camera(const view_control *c, const sl_camera *intrinsics);
/* Take a camera's pose (when following a path): position, yaw, pitch. */
void view_control_set(view_control *c, const sl_camera *cam);

/* ---- the HUD's text ---- */
typedef struct view_hud {
    const char *method;       /* the culler's method ("none": no culling) */
    const char *guarantee;    /* its guarantee's name, or NULL */
    uint32_t method_index, method_count;
    bool frozen, walk, recording, map;
    uint32_t recorded;        /* poses recorded */
    double frame_ms, cull_ms, draw_ms, gpu_ms; /* gpu_ms < 0: no timer queries */
    uint32_t objects_drawn, objects_total, draw_calls;
    uint64_t triangles_drawn, queries, query_stalls;
    sl_cull_stats cull;       /* the culler's counters */
    sl_vec3 position;
    float yaw, pitch, speed;  /* radians, m/s */
    double fps;               /* frames per second over the last second, 0 when unknown */
    const char *message;      /* a short note ("saved view-0001.png"), or NULL */
} view_hud;
/* The HUD's lines, '\n'-separated, into buf (always terminated). Returns the line count. */
uint32_t view_hud_text(const view_hud *h, char *buf, size_t size);

/* The keys, one per line (the --help text and the F1 overlay share it). */
extern const char view_keys_help[];

/* ---- --size WxH ---- */
bool view_parse_size(const char *text, uint32_t *w, uint32_t *h);

#endif

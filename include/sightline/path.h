/* Sightline camera paths: a sequence of timed poses plus the camera intrinsics they are viewed
 * with. Paths drive walkthroughs, benchmarks and the viewer.
 *
 * A pose is a time in seconds, an eye position and yaw/pitch/roll in radians with the conventions
 * of camera.h. Times never decrease along a path (equal times are allowed). The path's intrinsics
 * (projection, fov, near/far, viewport) are shared by every pose.
 *
 * Paths come from three places:
 *  - generators (sl_path_generate): a street-level walk or drive along the scene's street
 *    centre-line graph, or a flyover loop above the scene; deterministic for a given scene,
 *    options and seed;
 *  - random viewpoints (sl_path_random_views): independent poses for benchmarks;
 *  - the plain-text path file (sl_path_load/sl_path_save), documented in docs/paths.md:
 *        # sightline-path 1
 *        camera fov=60 near=0.1 far=5000 width=1024 height=768 projection=perspective
 *        # t x y z yaw pitch roll        (seconds, metres, degrees)
 *        0 10 20 1.7 90 0 0
 *    Saving then loading a path gives bit-identical poses and intrinsics.
 */
#ifndef SIGHTLINE_PATH_H
#define SIGHTLINE_PATH_H

#include "core.h"
#include "geom.h"
#include "camera.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_path_t *sl_path;

typedef struct sl_pose {
    float time;                 /* seconds */
    sl_vec3 position;           /* eye position, metres */
    float yaw, pitch, roll;     /* radians (camera.h); pitch in [-pi/2, pi/2] */
} sl_pose;

typedef enum sl_path_kind {
    SL_PATH_WALK = 0,           /* pedestrian on the sidewalk, eye 1.7 m above the ground, 1.4 m/s */
    SL_PATH_DRIVE = 1,          /* car in the right lane, eye 1.2 m above the ground, 50 km/h */
    SL_PATH_FLYOVER = 2         /* closed elliptic loop above the scene, looking 30 degrees down */
} sl_path_kind;

typedef enum sl_view_kind {
    SL_VIEWS_STREET = 0,        /* random point on a street, random yaw, level view */
    SL_VIEWS_FLYOVER = 1        /* random point above the scene, random yaw, looking down */
} sl_view_kind;

typedef struct sl_path_options {
    sl_path_kind kind;
    uint32_t frames;            /* poses to produce, in [1, 1e8] (default 600) */
    float fps;                  /* frames per second, in [0.001, 1000] (default 30) */
    float speed;                /* m/s, in [0.001, 10000]; flyover: 0 = one loop over the duration */
    float eye_height;           /* walk/drive/street views: eye above sl_scene_ground_height, >= 0 */
    float altitude;             /* flyover/flyover views: flight height above the scene's lowest
                                 * point, > 0; 0 = auto, from the scene's size w (across) and
                                 * height h: max(min(150, w/2), 1.5 h + min(50, w/2)) */
    float look_down;            /* flyover/flyover views: angle below the horizon, radians, [0, pi/2] */
    float lane_offset;          /* walk/drive/street views: distance right of the centre line as a
                                 * fraction of the street width, [0, 0.5] (0.4 sidewalk, 0.25 lane) */
    bool head_bob;              /* walk: 2.5 cm vertical bob and 0.4 degree nod per 0.7 m step */
    uint64_t seed;
    sl_camera intrinsics;       /* projection, fov, near/far, viewport stored with the path;
                                 * its position and angles are ignored */
} sl_path_options;

/* Statistics of a path. Speeds are over consecutive poses with distinct times. */
typedef struct sl_path_stats {
    uint32_t frames;
    double duration;            /* last time - first time, seconds */
    double length;              /* sum of distances between consecutive positions, metres */
    sl_aabb bounds;             /* of the positions (empty for an empty path) */
    double speed_min, speed_mean, speed_max; /* m/s; mean = the length of the timed steps / duration;
                                                0 when undefined */
    uint32_t jumps;             /* steps that move with no time between their poses (a cut or a
                                   teleport): in length, not in the speeds */
} sl_path_stats;

/* Defaults for a kind (see sl_path_options), intrinsics from sl_camera_default(). */
SL_API sl_path_options sl_path_options_default(sl_path_kind kind);

/* --- lifetime and contents ------------------------------------------------------------------- */

/* Create an empty path with the given intrinsics (NULL: sl_camera_default()). alloc may be NULL. */
SL_API sl_status sl_path_create(const sl_camera *intrinsics, const sl_allocator *alloc, sl_path *out, sl_error *err);
/* Release a path. NULL is ignored. */
SL_API void sl_path_destroy(sl_path path);
/* Append a pose: finite values, pitch in range, time not before the previous pose's. */
SL_API sl_status sl_path_append(sl_path path, const sl_pose *pose, sl_error *err);
/* Number of poses. */
SL_API uint32_t sl_path_count(sl_path path);
/* Contiguous array of sl_path_count() poses, valid until the path is changed or destroyed. */
SL_API const sl_pose *sl_path_poses(sl_path path);
/* The intrinsics shared by every pose (position and angles zero). */
SL_API sl_camera sl_path_intrinsics(sl_path path);
/* Replace the intrinsics (validated with sl_camera_validate; position and angles ignored). */
SL_API sl_status sl_path_set_intrinsics(sl_path path, const sl_camera *intrinsics, sl_error *err);
/* The camera of pose `index` (intrinsics + pose); the default camera when out of range. */
SL_API sl_camera sl_path_camera(sl_path path, uint32_t index);
/* Camera at time t for replay at another frame rate: linear position and pitch, shortest-arc yaw
 * and roll between the poses around t; t is clamped to the path's time range. At a pose's time
 * the pose is returned exactly (with equal times, the last such pose). Fails on an empty path or
 * a non-finite t. */
SL_API sl_status sl_path_sample(sl_path path, double t, sl_camera *out, sl_error *err);
/* Frame count, duration, length travelled, bounds and speeds. */
SL_API void sl_path_get_stats(sl_path path, sl_path_stats *out);

/* --- generators -------------------------------------------------------------------------------- */

/* Generate a walk, drive or flyover (opt NULL: walk defaults). Walk and drive follow the street
 * centre-line graph (sl_scene_street_graph), choosing turns at random (never reversing along the
 * edge just travelled unless it is a dead end) and easing the heading through each turn; they fail
 * with SL_ERROR_UNSUPPORTED on a scene without streets. A flyover works for any scene with
 * non-empty bounds (objects, streets or terrain). Deterministic for equal scene, options and seed. */
SL_API sl_status sl_path_generate(sl_scene scene, const sl_path_options *opt, const sl_allocator *alloc, sl_path *out,
                                  sl_error *err);
/* `count` independent random poses, one per second of path time (times 0, 1, 2, ...).
 * Street views stand on a random point of a random street (length-weighted), anywhere across the
 * street within lane_offset * width of the centre line, with a random yaw and zero pitch; without
 * streets, scene metadata "q3.spawns" ("x y z;x y z;..." eye positions) is used instead, otherwise
 * SL_ERROR_UNSUPPORTED. Flyover views pick x, y uniformly over the scene bounds at the flyover
 * altitude, a random yaw, and a pitch of -look_down +- 15 degrees (clamped to [-90, 0]).
 * opt may be NULL; its kind, frames, fps, speed, head_bob and seed are ignored. */
SL_API sl_status sl_path_random_views(sl_scene scene, sl_view_kind kind, uint32_t count, uint64_t seed,
                                      const sl_path_options *opt, const sl_allocator *alloc, sl_path *out,
                                      sl_error *err);

/* --- files ------------------------------------------------------------------------------------- */

/* Write a path file atomically (temporary file, then rename). */
SL_API sl_status sl_path_save(sl_path path, const char *file, sl_error *err);
/* Read and validate a path file; errors read "file:line: reason" (SL_ERROR_FORMAT). */
SL_API sl_status sl_path_load(const char *file, const sl_allocator *alloc, sl_path *out, sl_error *err);
/* Parse a path file held in memory; `name` stands for the file name in messages. */
SL_API sl_status sl_path_parse(const void *data, size_t size, const char *name, const sl_allocator *alloc,
                               sl_path *out, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

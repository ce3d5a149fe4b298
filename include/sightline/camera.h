/* Sightline cameras: perspective and orthographic, 6 degrees of freedom, frustum planes.
 *
 * World: metres, right-handed, Z up. Orientation by yaw, pitch, roll in radians:
 *   yaw   rotates about +Z, counter-clockwise seen from above; yaw 0 looks along +X, pi/2 along +Y;
 *   pitch tilts the view up (positive) or down, in [-pi/2, pi/2];
 *   roll  rotates about the viewing direction, positive is clockwise as seen by the viewer: the
 *         camera's up vector turns toward its right vector, so the image content turns
 *         counter-clockwise on screen.
 * forward = (cos(pitch)cos(yaw), cos(pitch)sin(yaw), sin(pitch)); up (roll 0) has a positive z
 * (for |pitch| < pi/2; at +-pi/2 yaw alone orients the image).
 * The view matrix maps to OpenGL eye space (camera looks down -Z_eye, Y_eye up); projection maps to
 * clip space with OpenGL conventions (NDC z in [-1,1]); matrices are column-major (sl_mat4).
 */
#ifndef SIGHTLINE_CAMERA_H
#define SIGHTLINE_CAMERA_H

#include "core.h"
#include "geom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sl_projection { SL_PERSPECTIVE = 0, SL_ORTHOGRAPHIC = 1 } sl_projection;

typedef struct sl_camera {
    sl_vec3 position;
    float yaw, pitch, roll;     /* radians */
    sl_projection projection;
    float fov_y;                /* perspective: vertical field of view, radians, in (0, pi) */
    float ortho_height;         /* orthographic: height of the view volume in metres */
    float near_plane, far_plane;/* > 0, far > near */
    uint32_t width, height;     /* viewport in pixels (aspect = width/height) */
} sl_camera;

/* Frustum planes, inside where a*x+b*y+c*z+d >= 0; order: left, right, bottom, top, near, far. */
typedef struct sl_frustum {
    sl_plane planes[6];
    sl_vec3 corners[8];         /* near (bl, br, tr, tl) then far (bl, br, tr, tl) */
} sl_frustum;

/* How a consumer of the camera's float world-to-clip matrix stores depth (issue 12: a projection
 * the format cannot resolve is refused, not culled wrongly):
 *  NONE    the frustum planes only (vfc, the 2.5D methods, frusta's object-space shadows);
 *  INV_W   1/w_clip in float (the conservative rasterizer of hzb, hom, lazygrid, busygrid, plp);
 *  CLIP_Z  (1 - z_clip/w_clip)/2 in float, the renderer's depth (the oracle, hzb's exact layer).
 * Orthographic cameras store linear depth and are not limited here. */
typedef enum sl_depth_format { SL_DEPTH_NONE = 0, SL_DEPTH_INV_W = 1, SL_DEPTH_CLIP_Z = 2 } sl_depth_format;

/* The largest far/near ratio CLIP_Z resolves: beyond it (far/near > 2^24) the float matrix's
 * (f+n)/(f-n) rounds to 1 and the far plane is lost. INV_W has no such limit. */
#define SL_CAMERA_MAX_FAR_NEAR 16777216.0

/* The least near plane (metres) a depth format resolves for this camera (perspective; 0 for NONE
 * and for orthographic cameras): 2^-20 of (|x| + |y| + |z| + 1 m) of the eye, below which the
 * float rounding of the matrix's translation (2^-24 of the eye's coordinates per entry) rivals
 * the depth term 2*near and the order of depths along a ray is lost; for CLIP_Z at least
 * far / SL_CAMERA_MAX_FAR_NEAR too. */
SL_API double sl_camera_min_near(const sl_camera *cam, sl_depth_format format);
/* Check a validated camera against a depth format for `who` (a method's name, "the oracle"):
 * SL_ERROR_INVALID_ARGUMENT naming the near plane and the limit, e.g. "near plane 1e-30 m: hzb's
 * float depth (1 - z/w)/2 needs near >= 0.000298 m (2^-20 of |x|+|y|+|z|+1 m at this eye, and
 * far/near <= 16777216)". */
SL_API sl_status sl_camera_check_depth(const sl_camera *cam, sl_depth_format format, const char *who, sl_error *err);

/* A default camera: at the origin, 1.7 m up, looking along +X, 60 degrees vertical fov,
 * 1024x768, near 0.1 m, far 5000 m (ortho_height 100 m, used when switched to orthographic). */
SL_API sl_camera sl_camera_default(void);
/* Check a camera (finite values, ranges above); the message names the bad field. */
SL_API sl_status sl_camera_validate(const sl_camera *cam, sl_error *err);
/* Unit forward, right and up vectors. */
SL_API void sl_camera_basis(const sl_camera *cam, sl_vec3 *forward, sl_vec3 *right, sl_vec3 *up);
/* World-to-eye, eye-to-clip and world-to-clip matrices. */
SL_API sl_mat4 sl_camera_view(const sl_camera *cam);
SL_API sl_mat4 sl_camera_proj(const sl_camera *cam);
SL_API sl_mat4 sl_camera_view_proj(const sl_camera *cam);
/* Frustum planes (normalised) and corners in world space. */
SL_API sl_frustum sl_camera_frustum(const sl_camera *cam);
/* Point the camera at a target (sets yaw and pitch, keeps roll). */
SL_API void sl_camera_look_at(sl_camera *cam, sl_vec3 target);

/* Box-frustum classification: 0 outside, 1 intersecting, 2 fully inside (p-vertex/n-vertex test
 * against each plane). Conservative: a box outside the frustum near an edge or corner may be
 * reported as intersecting, never the reverse. An empty box is outside. */
SL_API int sl_frustum_test_aabb(const sl_frustum *f, const sl_aabb *box);

/* Read "x,y,z,yaw,pitch,roll[,fov]" (metres, degrees) into cam's position, yaw, pitch, roll and,
 * with a seventh number, fov_y (radians); every value finite as a float. Other fields are
 * untouched, and so is cam on failure. The camera's own checks (sl_camera_validate) still apply
 * afterwards. The `render` command's --camera. Pure, thread-safe. */
SL_API bool sl_parse_camera_spec(const char *text, sl_camera *cam);

#ifdef __cplusplus
}
#endif
#endif

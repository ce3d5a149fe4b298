/* Sightline views: what every culler, the oracles and the bench cull and render from.
 *
 * An sl_view is a value filled only by its constructors: from an sl_camera (sl_view_from_camera,
 * the symmetric yaw/pitch/roll + fov frustum of camera.h) or from an engine's own column-major
 * view and projection matrices (sl_view_from_matrices: OpenGL, D3D/Vulkan/Metal [0,1] and
 * reversed-z depth, right- or left-handed eye space, off-axis, x- or y-flipped, perspective or
 * orthographic, finite or infinite far plane). Do not fill or edit one by hand: the cullers refuse
 * a view no constructor made.
 *
 * Normal form. Whatever the input, a view holds matrices in ONE convention, that of camera.h:
 *   view  world -> eye, rigid (3x3 part orthonormal, det +1), eye space right-handed, the eye
 *         looking down -Z_eye, +Y_eye up;
 *   proj  eye -> clip, OpenGL depth (NDC z in [-1, 1], near -> -1), w_clip = -z_eye (perspective)
 *         or 1 (orthographic), x and y scales positive (an unmirrored image).
 * view_proj = proj * view is the engine's world -> clip map up to (a) the depth convention and (b)
 * a mirror of the image in x and/or y (mirrored_x / mirrored_y say which). Visible sets do not
 * change under a mirror; screen winding does, so the normal form has the winding of an unmirrored
 * OpenGL view: a triangle is front-facing when it winds counter-clockwise seen from the eye, for a
 * view from matrices as for one from a camera, whatever the engine's own image orientation.
 *
 * Thread safety: every function here is pure (no shared state); views are plain values.
 */
#ifndef SIGHTLINE_VIEW_H
#define SIGHTLINE_VIEW_H

#include "core.h"
#include "geom.h"
#include "camera.h"

#ifdef __cplusplus
extern "C" {
#endif

/* How an engine's projection matrix maps depth (NDC z = z_clip / w_clip):
 *  GL        OpenGL: near -> -1, far -> +1;
 *  ZERO_ONE  Direct3D, Vulkan, Metal: near -> 0, far -> 1;
 *  REVERSED  reversed-z [0, 1]: near -> 1, far -> 0 (finite far, or infinite: far -> 0 at infinity). */
typedef enum sl_clip_depth {
    SL_CLIP_DEPTH_GL = 0,
    SL_CLIP_DEPTH_ZERO_ONE = 1,
    SL_CLIP_DEPTH_REVERSED = 2
} sl_clip_depth;

typedef enum sl_view_source { SL_VIEW_FROM_CAMERA = 1, SL_VIEW_FROM_MATRICES = 2 } sl_view_source;

/* Tolerance of sl_view_from_matrices on the view matrix: every dot product of two rows of its 3x3
 * part within SL_VIEW_ORTHO_TOL of the identity's (0 or 1), and its bottom row (0, 0, 0, 1)
 * within it; on the projection matrix: the entries that must be zero (skew, shear, oblique
 * depth) within SL_VIEW_ORTHO_TOL times the larger of |P00| and |P11|, and the bottom row within
 * SL_VIEW_ORTHO_TOL of (0, 0, +-1, 0) or (0, 0, 0, 1). Entries accepted within it are taken as
 * exactly 0 (or 1) in the normal form. */
#define SL_VIEW_ORTHO_TOL 1e-5

typedef struct sl_view {
    sl_mat4 view;               /* world -> eye (normal form above), column-major */
    sl_mat4 proj;               /* eye -> clip, OpenGL depth; with an infinite far plane the
                                   OpenGL infinite form (P22 = -1, P23 = -2 near); Pij is row i, column j */
    sl_mat4 view_proj;          /* proj * view (accumulated in double, rounded once) */
    sl_projection projection;
    sl_vec3 eye;                /* centre of projection (orthographic: the eye-space origin) */
    sl_vec3 forward, right, up; /* unit world axes of eye space: -Z_eye, +X_eye, +Y_eye */
    double near_plane, far_plane; /* eye-space distances along forward, 0 < near < far; far may be
                                   INFINITY (then sl_view_bound_far gives a finite one) */
    /* the near rectangle in eye space: x in [rect_left, rect_right], y in [rect_bottom, rect_top]
     * at the near plane (perspective: the side planes pass through the eye and these edges) or
     * the whole volume (orthographic); off-axis views have l != -r or b != -t */
    double rect_left, rect_right, rect_bottom, rect_top;
    /* pixels per metre of eye-space x and y at unit forward distance (perspective) or per metre
     * (orthographic): P00 * width / 2 and P11 * height / 2 */
    double focal_x, focal_y;
    /* perspective: distance from the eye of the farthest near-rectangle corner (0 orthographic) */
    double near_corner_dist;
    uint32_t width, height;     /* viewport in pixels */
    sl_frustum frustum;         /* world-space planes (normalised, inward) and corners, built
                                   geometrically in double from the above; with an infinite far
                                   plane, planes[5] is (0, 0, 0, 1) (always inside) and the far
                                   corners are not finite */
    sl_view_source source;
    sl_clip_depth clip_depth;   /* the convention of the input (GL for a camera) */
    bool mirrored_x, mirrored_y;/* normalisation mirrored the input's image in x / in y (e.g. a
                                   Vulkan y-down projection gives mirrored_y) */
    bool left_handed;           /* the input's eye space was left-handed (det of the view's 3x3 -1) */
    sl_camera camera;           /* source == SL_VIEW_FROM_CAMERA: the camera (else zero) */
    uint32_t magic;             /* set by the constructors */
} sl_view;

/* A view of a camera (validated by sl_camera_validate): view, proj, view_proj and frustum are
 * exactly (bit for bit) sl_camera_view, sl_camera_proj, sl_camera_view_proj and
 * sl_camera_frustum of the camera, forward/right/up sl_camera_basis, eye its position. */
SL_API sl_status sl_view_from_camera(const sl_camera *cam, sl_view *out, sl_error *err);

/* A view of an engine's column-major view (world -> eye) and projection (eye -> clip) matrices
 * with depth convention `depth` and a viewport of width x height pixels, normalised as above.
 * Accepted: a view matrix whose 3x3 part is orthonormal of either handedness (SL_VIEW_ORTHO_TOL)
 * with bottom row (0, 0, 0, 1); a perspective projection (bottom row (0, 0, -1, 0) for a
 * right-handed eye space looking down -Z, (0, 0, 1, 0) for one looking down +Z) or an
 * orthographic one (bottom row (0, 0, 0, 1)), with off-axis terms (perspective P02, P12;
 * orthographic P03, P13), negative P00 or P11 (mirrored images), finite or (perspective)
 * infinite far. Refused with SL_ERROR_INVALID_ARGUMENT and a message naming the matrix, the
 * element and the reason: a non-finite entry, a scaled, skewed or singular view matrix, a
 * projection with skew (P01, P10), an oblique or x/y-dependent depth row (P20, P21), shear (an
 * orthographic P02, P12; a perspective P03, P13), another bottom row, a zero scale, a near plane
 * <= 0 (orthographic too), a far plane not beyond the near plane, a zero viewport. */
SL_API sl_status sl_view_from_matrices(const float view[16], const float proj[16], sl_clip_depth depth,
                                       uint32_t width, uint32_t height, sl_view *out, sl_error *err);

/* Check that v was made by a constructor (SL_ERROR_INVALID_ARGUMENT otherwise, or when NULL). */
SL_API sl_status sl_view_validate(const sl_view *v, sl_error *err);

/* A copy of view v with its far plane at `far_plane` (> near; INFINITY allowed for perspective):
 * for a view of a camera, the view of the camera with that far plane (rounded to float). */
SL_API sl_status sl_view_with_far(const sl_view *v, double far_plane, sl_view *out, sl_error *err);
/* A copy of v with another viewport: for a view of a camera, the camera's view at that size (its
 * aspect follows); for a view of matrices, the same matrices (only the pixel size changes). */
SL_API sl_status sl_view_with_viewport(const sl_view *v, uint32_t width, uint32_t height, sl_view *out, sl_error *err);

/* Replace an infinite far plane, or one beyond the world, by one just beyond the farthest corner
 * of the box `world` from the eye (its distance * (1 + 1e-3) + 1 m, at least twice the near
 * plane): every point of the frustum within `world` stays inside, so the visible set of a scene
 * inside `world` does not change. A view whose far plane is already nearer is copied unchanged.
 * sl_culler_cull_view and the oracle apply it (with the scene's bounds) to a view with an infinite
 * far plane, so the methods never see one. */
SL_API sl_status sl_view_bound_far(const sl_view *v, const sl_aabb *world, sl_view *out, sl_error *err);

/* The depth-format limits of camera.h for a view: the least near plane a depth format resolves
 * (2^-20 of |x|+|y|+|z|+1 m at the eye; for CLIP_Z at least far / SL_CAMERA_MAX_FAR_NEAR, infinite
 * for an infinite far plane), 0 for SL_DEPTH_NONE and orthographic views; and the check naming the
 * near plane and the limit for `who` (sl_camera_min_near and sl_camera_check_depth call these). */
SL_API double sl_view_min_near(const sl_view *v, sl_depth_format format);
SL_API sl_status sl_view_check_depth(const sl_view *v, sl_depth_format format, const char *who, sl_error *err);

/* The sight line of image point (x, y) of the view's normal form, in pixels from the top-left
 * corner (a pixel's centre at +0.5; row 0 at the top of the unmirrored image): the inverse of the
 * projection in double, through the near rectangle. Perspective: org is the eye and dir has a unit
 * component along forward (a hit at parameter t lies at depth t: the near and far planes are t =
 * near and t = far); orthographic: org on the eye plane, dir = forward. */
SL_API void sl_view_pixel_ray(const sl_view *v, double x, double y, double org[3], double dir[3]);

/* "gl", "zero-one" or "reversed"; and back (false for anything else). */
SL_API const char *sl_clip_depth_name(sl_clip_depth d);
SL_API bool sl_clip_depth_parse(const char *text, sl_clip_depth *out);

#ifdef __cplusplus
}
#endif
#endif

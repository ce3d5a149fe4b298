/* The inside of camera.c for the view constructor (core only). */
#ifndef SL_CAMERA_INTERNAL_H
#define SL_CAMERA_INTERNAL_H

#include "sightline/camera.h"

/* sl_camera_view, sl_camera_proj, sl_camera_view_proj, sl_camera_frustum and sl_camera_basis of a
 * camera in one call, bit for bit the same values, with the basis and tan(fov_y / 2) computed once
 * (sl_view_from_camera runs once per culled frame); *tan_half_fov_y is 0 for orthographic cameras. */
void sl_camera_all(const sl_camera *cam, sl_mat4 *view, sl_mat4 *proj, sl_mat4 *view_proj, sl_frustum *frustum,
                   sl_vec3 *forward, sl_vec3 *right, sl_vec3 *up, double *tan_half_fov_y);

#endif

/* Sightline urban 2.5D culling: extras of the cull-map method beyond the culler interface.
 *
 * The urban methods themselves (cullmap, horizon, dhorizon) are cullers: create them by name with
 * sl_culler_create (cull.h); docs/urban.md describes them, their options and guarantees. */
#ifndef SIGHTLINE_URBAN_H
#define SIGHTLINE_URBAN_H

#include "core.h"
#include "camera.h"
#include "scene.h"
#include "view.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Write the cull map of one viewpoint over the top-down city as an RGB PNG (written atomically):
 * one square of a few pixels per grid cell, north up. Cells outside the frustum's ground plan show
 * the city's heights in grey; cells in view show the height below which everything is hidden on a
 * dark-blue-to-yellow ramp, or off-white where nothing is hidden; footprint outlines are green for
 * buildings reported visible and dark otherwise; the frustum's plan is blue and the eye red.
 * options: the cullmap culler's options ("cell=4,radius=800"; NULL or "" for the defaults). */
SL_API sl_status sl_cullmap_render_png(sl_scene scene, const sl_camera *cam, const char *options, const char *path,
                                       sl_error *err);
/* The same for a view (view.h: from a camera or an engine's matrices; an infinite far plane is
 * bounded by the scene, as sl_culler_cull_view does): the cells and outlines are those of the
 * cullmap culler culling that view. For sl_view_from_camera(cam) the PNG is byte for byte that of
 * sl_cullmap_render_png(cam). */
SL_API sl_status sl_cullmap_render_png_view(sl_scene scene, const sl_view *view, const char *options, const char *path,
                                            sl_error *err);

#ifdef __cplusplus
}
#endif
#endif
